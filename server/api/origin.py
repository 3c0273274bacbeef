"""Same-origin check for WebSocket routes.

Browsers do not apply the same-origin policy to WebSockets: any page a user opens may
connect to the console's sockets with the user's network position behind it (and, once
there are any, the user's cookies). What a browser does send is the page's ``Origin``; a
socket that only the console's own pages should open compares it with the request's own
scheme and ``Host``. A request without ``Origin`` does not come from a browser page (a
script, ``websocat``, a test) and cannot be riding on a user's browser, so it is let
through: the check defends against cross-site pages, not against clients that choose
their own headers (authentication is for those).
"""

from __future__ import annotations

from collections.abc import Mapping
from urllib.parse import urlsplit

# A WebSocket's own scheme and the scheme of the page that may open it.
PAGE_SCHEME = {"ws": "http", "wss": "https", "http": "http", "https": "https"}
DEFAULT_PORT = {"http": 80, "https": 443}


def _host_port(netloc: str, scheme: str) -> tuple[str, int] | None:
    """``(host, port)`` of ``host[:port]`` (IPv6 in brackets), the scheme's default port
    when none is given; None when it is not a plain host and port."""
    if not netloc or any(c in netloc for c in "@/?#\\ \t"):
        return None
    try:
        parts = urlsplit(f"//{netloc}")
        host, port = parts.hostname, parts.port
    except ValueError:  # a port that is not a number or out of range
        return None
    if not host:
        return None
    return host.lower(), DEFAULT_PORT[scheme] if port is None else port


def origin_allowed(headers: Mapping[str, str], scheme: str) -> bool:
    """Whether a request with ``headers`` (case-insensitive, as Starlette's) and its own
    ``scheme`` (``ws``, ``wss``, ``http`` or ``https``) may be served: no ``Origin``, or an
    ``Origin`` whose scheme, host and port are the request's own (``Host`` header; default
    ports count as given). A malformed or ``null`` Origin is refused.

    >>> origin_allowed({"host": "rover.example:8000", "origin": "http://rover.example:8000"}, "ws")
    True
    >>> origin_allowed({"host": "rover.example:8000", "origin": "http://evil.example"}, "ws")
    False
    >>> origin_allowed({"host": "rover.example:8000"}, "ws")
    True
    """
    origin = headers.get("origin")
    if origin is None:
        return True
    page_scheme = PAGE_SCHEME.get(scheme.lower())
    host = headers.get("host")
    if page_scheme is None or host is None:
        return False
    try:
        parts = urlsplit(origin.strip())
    except ValueError:
        return False
    origin_scheme = parts.scheme.lower()
    if origin_scheme != page_scheme or parts.path or parts.query or parts.fragment:
        return False
    ours = _host_port(host.strip(), page_scheme)
    theirs = _host_port(parts.netloc, page_scheme)
    return ours is not None and ours == theirs
