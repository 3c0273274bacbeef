"""Errors raised for bad input from outside (CLI arguments, scenario parameters)."""


class InputError(ValueError):
    """A value from outside is invalid; the message names the parameter.

    The CLI turns it into a one-line message and a non-zero exit, never a traceback.
    """

    def __init__(self, parameter: str, problem: str) -> None:
        super().__init__(f"{parameter}: {problem}")
        self.parameter = parameter
        self.problem = problem
