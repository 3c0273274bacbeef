"""Reading request bodies without trusting them: size, nesting, numbers and concurrency.

Every body the server reads goes through here (issue 13, defects 2, 5 and 6):

- ``read_body`` counts the bytes while they arrive (``request.stream()``: chunked bodies
  too) and refuses with 413 as soon as they pass the limit, so a 300 MB body costs at most
  the limit and one chunk of memory, never the whole body.
- ``parse_json`` refuses, with a 422 naming the problem, what Python's ``json`` would turn
  into a 500 or into something a JSON response cannot carry: nesting deeper than
  ``MAX_JSON_DEPTH`` (found by a linear pre-scan before the recursive parser sees it), an
  integer over Python's 4,300-digit conversion limit, and ``NaN``/``Infinity``/``1e999``.
- ``read_source`` turns an upload's bytes (text, JSON or multipart) into the sequence source;
  it is synchronous and runs with the validation, off the event loop (in the validation
  worker process, ``server.validation.pool``, or the threadpool).
- ``ValidationSlots`` bounds the validations one client runs at once (per address, and per
  token when one is sent): over it, 429 with ``Retry-After``.

Every 422 ``detail`` here has FastAPI's own shape, a list of ``{"loc", "msg", "type"}``,
so one schema describes every 422 of the API.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import re
from collections import Counter
from collections.abc import Iterator
from typing import Any

import numpy as np
from fastapi import HTTPException, Request
from python_multipart.exceptions import FormParserError
from python_multipart.multipart import Field, File, create_form_parser

MAX_JSON_DEPTH = 64  # arrays and objects inside each other; a sequence needs 4
RETRY_AFTER_S = 1  # what a 429 asks the client to wait
_KIND = {"addr": "client address", "token": "token"}


def request_error(loc: tuple[str | int, ...], msg: str, kind: str) -> HTTPException:
    """A 422 whose ``detail`` is FastAPI's validation-error list (one entry)."""
    return HTTPException(422, [{"loc": list(loc), "msg": msg, "type": kind}])


def too_large(limit: int) -> HTTPException:
    """The 413 of a body over ``limit`` bytes, naming the limit as README.md and
    docs/sequences.md give it (in MB, 10^6 bytes) and in bytes.

    >>> too_large(1_000_000).detail
    'body over the upload limit of 1 MB (1000000 bytes)'
    """
    return HTTPException(413, f"body over the upload limit of {limit / 1e6:g} MB ({limit} bytes)")


async def read_body(request: Request, limit: int) -> bytes:
    """The request body, refused (413) once more than ``limit`` bytes have arrived: a
    declared Content-Length over the limit before any byte is read, a chunked body after
    at most the limit and one chunk."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise too_large(limit)
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise too_large(limit)
        chunks.append(chunk)
    return b"".join(chunks)


_STRING = b'"(?:[^"\\\\]|\\\\.)*"'
_BRACKETS = bytes.maketrans(b"[{]}", b"\x02\x02\x00\x00")
_NOT_BRACKETS = bytes(c for c in range(256) if c not in b"[{]}")


def json_depth(data: bytes) -> int:
    """How deep arrays and objects nest in ``data`` (JSON text), in linear time: strings
    removed, then a running sum of opening (+1) and closing (-1) brackets. Malformed text
    gives a number too (the parser refuses it afterwards).

    >>> json_depth(b'{"steps": [{"args": {"x": "[[[["}}]}')
    4
    """
    stripped = re.sub(_STRING, b'""', data, flags=re.DOTALL)
    steps = stripped.translate(_BRACKETS, _NOT_BRACKETS)
    if not steps:
        return 0
    return int(np.cumsum(np.frombuffer(steps, dtype=np.uint8).astype(np.int64) - 1).max())


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is out of range for a number")
    return value


def parse_json(data: bytes, where: str = "body") -> Any:
    """JSON ``data`` parsed, or a 422 naming the problem (``where`` starts its message)."""
    depth = json_depth(data)
    if depth > MAX_JSON_DEPTH:
        raise request_error(
            (where,), f"{where}: JSON nested {depth} deep; at most {MAX_JSON_DEPTH}", "json_depth"
        )
    try:
        return json.loads(data, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise request_error((where,), f"{where}: not JSON: {exc}", "json_invalid") from exc
    except UnicodeDecodeError as exc:
        raise request_error((where,), f"{where}: not UTF-8 ({exc.reason})", "json_invalid") from exc
    except (ValueError, RecursionError) as exc:  # over 4,300 digits; NaN; 1e999
        reason = str(exc)
        if "4300 digits" in reason:  # Python's int conversion limit (sys.int_info)
            reason = "an integer of more than 4300 digits"
        raise request_error((where,), f"{where}: {reason}", "json_invalid") from exc


def decode(data: bytes, where: str) -> str:
    """UTF-8 text, or a 422 naming ``where``."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise request_error((where,), f"{where}: not UTF-8 text ({exc.reason})", "utf8") from exc


def _multipart_file(body: bytes, content_type: str) -> tuple[bytes, str]:
    """The ``file`` part of a multipart/form-data body: its bytes and file name."""
    found: list[tuple[bytes, str]] = []

    def on_file(part: File) -> None:
        if part.field_name == b"file":
            part.file_object.seek(0)
            name = (part.file_name or b"upload").decode("utf-8", "replace")
            found.append((part.file_object.read(), name))

    def on_field(part: Field) -> None:
        if part.field_name == b"file":
            found.append((part.value or b"", "upload"))

    headers = {"Content-Type": content_type.encode("latin-1", "replace")}
    try:
        parser = create_form_parser(
            headers, on_field, on_file, config={"MAX_MEMORY_FILE_SIZE": len(body) + 1}
        )
        parser.write(body)
        parser.finalize()
    except (FormParserError, ValueError) as exc:
        message = f"body: bad multipart/form-data: {exc}"
        raise request_error(("body",), message, "multipart") from exc
    if not found:
        raise request_error(("body", "file"), "multipart upload needs a 'file' part", "missing")
    return found[0]


def read_source(body: bytes, content_type: str) -> tuple[str | dict[str, Any], str]:
    """An upload's sequence source and format (``text`` or ``json``) from its bytes: a
    multipart ``file`` part (JSON if its name ends ``.json``), a JSON body (``{"text": ...}``,
    ``{"sequence": ...}``, a sequence object, or a list of steps), or else UTF-8 text."""
    if content_type.startswith("multipart/form-data"):
        data, name = _multipart_file(body, content_type)
        return decode(data, name), "json" if name.endswith(".json") else "text"
    if content_type.startswith("application/json"):
        parsed = parse_json(body)
        if isinstance(parsed, dict) and "text" in parsed:
            if not isinstance(parsed["text"], str):
                raise request_error(("body", "text"), "body.text: must be a string", "string_type")
            return parsed["text"], "text"
        if isinstance(parsed, dict) and "sequence" in parsed:
            inner = parsed["sequence"]
            if not isinstance(inner, dict | list):
                message = "body.sequence: must be a sequence object or a list of steps"
                raise request_error(("body", "sequence"), message, "json_type")
            return inner if isinstance(inner, dict) else {"steps": inner}, "json"
        if isinstance(parsed, dict | list):
            return parsed if isinstance(parsed, dict) else {"steps": parsed}, "json"
        raise request_error(
            ("body",), "body: a sequence object, a list of steps, or {'text': ...}", "json_type"
        )
    return decode(body, "body"), "text"


def client_keys(request: Request) -> list[str]:
    """Who a request counts against: its client address, and its token when it sends one
    (hashed: the slots never hold a token)."""
    keys = [f"addr:{request.client.host if request.client else '?'}"]
    token = request.headers.get("x-operator-token")
    authorization = request.headers.get("authorization", "")
    if authorization.lower().startswith("bearer "):
        token = authorization[7:].strip()
    if token:
        keys.append("token:" + hashlib.sha256(token.encode()).hexdigest()[:16])
    return keys


class ValidationSlots:
    """At most ``per_client`` validations at once per client key (``client_keys``). Used
    from the event loop only (no lock needed)."""

    def __init__(self, per_client: int) -> None:
        self.per_client = per_client
        self.running: Counter[str] = Counter()

    @contextlib.contextmanager
    def hold(self, request: Request) -> Iterator[None]:
        """A slot for this request's client for the ``with`` block, or 429."""
        keys = client_keys(request)
        busy = [_KIND[k.split(":")[0]] for k in keys if self.running[k] >= self.per_client]
        if busy:
            raise HTTPException(
                429,
                f"too many validations at once from this {' and '.join(busy)}"
                f" (at most {self.per_client}); retry when one has finished",
                {"Retry-After": str(RETRY_AFTER_S)},
            )
        self.running.update(keys)
        try:
            yield
        finally:
            self.running.subtract(keys)
            for k in keys:
                if self.running[k] <= 0:
                    del self.running[k]
