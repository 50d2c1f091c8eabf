"""Safe reading of the JSON inputs (vehicle file, ``--fit`` file, route file): one home for the checks.

Every JSON the command line reads goes through :func:`load_json_file` (or :func:`loads_json` for
text): the encoding is checked first (UTF-16/32 text and binary files are refused naming the
file, a UTF-8 byte-order mark is fine), the nesting depth is measured before parsing (a file
nested 200,000 levels deep made Python's parser raise ``RecursionError``), and syntax errors
name the line and column. Errors are :class:`~soiltrack.soilmodel.errors.DataError`.
"""

from __future__ import annotations

import json
import os
import re
from typing import Any

import numpy as np

from .csvread import check_encoding
from .errors import DataError

__all__ = ["MAX_JSON_DEPTH", "MAX_JSON_BYTES", "load_json_file", "loads_json", "json_depth"]

#: Deepest nesting of objects and lists accepted. The library's JSON formats nest at most 4
#: levels (route -> patches -> patch -> soil; fit -> covariance -> matrix -> row).
MAX_JSON_DEPTH = 64
#: Largest JSON input read, bytes (a fit JSON of a 2-million-row log is a few MB: its residuals
#: are not in it).
MAX_JSON_BYTES = 64 * 1024 * 1024

_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(text: str) -> int:
    """Deepest nesting of ``{``/``[`` in JSON text (brackets inside strings not counted)."""
    bare = _STRING.sub('""', text).encode("utf-8", "replace")
    b = np.frombuffer(bare, dtype=np.uint8)
    if b.size == 0:
        return 0
    step = ((b == ord("{")) | (b == ord("["))).astype(np.int32) - ((b == ord("}")) | (b == ord("]"))).astype(np.int32)
    return int(max(np.cumsum(step).max(), 0))


def loads_json(text: str, source: str = "<json text>", what: str = "JSON") -> Any:
    """Parse JSON text after the depth check; DataError naming ``source`` otherwise."""
    depth = json_depth(text)
    if depth > MAX_JSON_DEPTH:
        raise DataError(
            f"the {what} is nested {depth:,} levels deep; at most {MAX_JSON_DEPTH} are read (this "
            "format nests a few levels: not a file of this kind?)",
            file=source,
        )
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise DataError(f"invalid JSON at line {e.lineno}, column {e.colno}: {e.msg}", file=source) from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise DataError(f"the {what} is nested too deeply to read", file=source) from None


def load_json_file(path: str | os.PathLike, what: str = "JSON file") -> Any:
    """Read and parse a UTF-8 JSON file (see the module notes); DataError naming the file otherwise."""
    src = os.fspath(path)
    try:
        with open(src, "rb") as fh:
            raw = fh.read(MAX_JSON_BYTES + 1)
    except OSError as e:
        raise DataError(f"cannot read the {what}: {e.strerror}", file=src) from None
    if len(raw) > MAX_JSON_BYTES:
        raise DataError(f"the {what} is larger than {MAX_JSON_BYTES // 2**20} MB: not a file of this kind?", file=src)
    check_encoding(src, raw[:4096], what)
    try:
        text = raw.decode("utf-8-sig")  # a UTF-8 byte-order mark (Windows editors) is fine
    except UnicodeDecodeError as e:
        raise DataError(f"not a UTF-8 text file (byte {e.start}): save the {what} as UTF-8", file=src) from None
    return loads_json(text, src, what)
