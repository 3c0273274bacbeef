"""``roverops bench comm`` (``bench.comm.report``): the link across light time measured
through the server, its light time checked against a second computation (``light``), sols
in-process (``sols``), a server killed mid-pass (``kills``), the checks they share
(``checks``)."""
