"""An upload's path to the validator: its body read within the limits and parsed into a
sequence source (``uploads``, which also holds a client's validation slots), what the
validator needs to know of the rover (``context``), and the worker processes that validate
off the server's interpreter (``pool``)."""
