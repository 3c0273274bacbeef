"""The HTTP and WebSocket API: one router per resource (``routes`` in each module) and the
dependencies they share (``deps``); the token checked before the body is read
(``routing``) and the origin of a WebSocket (``origin``). An upload's body is read and
parsed by ``server.validation.uploads``."""
