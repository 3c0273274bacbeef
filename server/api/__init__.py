"""The HTTP and WebSocket API: one router per resource (``routes`` in each module), the
dependencies they share (``deps``), and the request plumbing under them: the token checked
before the body is read (``routing``), the body's size and shape (``uploads``), the origin
of a WebSocket (``origin``)."""
