r"""Line numbers of the keys of a TOML text (Python's :mod:`tomllib` keeps none).

:func:`key_lines` scans the text for table headers, ``key = value`` lines and the keys of
inline tables; :func:`show_key` writes a key path as a user writes it. Used by the study-file
checker (:mod:`podkrig.study.schema`) to name the line of an invalid key.

Example
-------
>>> key_lines('a = 1\n[t]\nb = { c = 2 }\n')[("t", "b", "c")]
3
>>> show_key(("validation", 1, "n"))
'validation[2].n'
"""

import re

__all__ = ["key_lines", "show_key"]

_BARE = r"[A-Za-z0-9_-]+"
_QUOTED = r'"(?:[^"\\]|\\.)*"|\'[^\']*\''
_KEY = rf"(?:{_BARE}|{_QUOTED})(?:\s*\.\s*(?:{_BARE}|{_QUOTED}))*"
_KEY_LINE = re.compile(rf"^\s*({_KEY})\s*=(.*)$")
_HEADER = re.compile(rf"^\s*(\[\[?)\s*({_KEY})\s*\]\]?\s*(?:#.*)?$")
_TOKEN = re.compile(rf"{_QUOTED}|[{{}}\[\],=]|{_BARE}|\S")


def _split_key(text):
    parts = re.findall(rf"{_BARE}|{_QUOTED}", text)
    return tuple(p[1:-1] if p[0] in "\"'" else p for p in parts)


def _inline_keys(rest, base, lineno, lines):
    """Record the keys of inline tables in ``rest`` (the text after ``key =``) under ``base``."""
    stack = []  # per open bracket: ("table", its key path or None) or ("array", None)
    value_path = base  # key path of the value being read; None inside arrays (not recorded)
    parts = None  # parts of the key being read inside an inline table
    for tok in _TOKEN.findall(rest):
        if parts is not None:
            if tok == "=":
                table = stack[-1][1]
                value_path = None if table is None else table + tuple(parts)
                if value_path is not None:
                    lines.setdefault(value_path, lineno)
                parts = None
            elif tok == "}":  # an empty inline table
                stack.pop()
                parts = None
            elif tok != ".":
                parts.append(tok[1:-1] if tok[0] in "\"'" else tok)
        elif tok == "#":
            break
        elif tok == "{":
            stack.append(("table", value_path))
            parts = []
        elif tok == "[":
            stack.append(("array", None))
            value_path = None
        elif tok in ("]", "}") and stack:
            stack.pop()
            value_path = None
        elif tok == "," and stack and stack[-1][0] == "table":
            parts = []


def key_lines(text):
    """Line (1-based) of every key and table of a TOML text.

    Parameters
    ----------
    text : str

    Returns
    -------
    dict of tuple to int
        Key path → line. Paths are tuples of keys; the ``k``-th ``[[name]]`` table is
        ``("name", k)`` (k from 0). Keys of inline tables share their line. Keys inside
        multi-line arrays are not listed (their array's key is).
    """
    lines = {}
    table = ()
    arrays = {}
    in_string = None
    for lineno, line in enumerate(text.splitlines(), start=1):
        if in_string:
            if in_string in line:
                in_string = None
            continue
        m = _HEADER.match(line)
        if m:
            path = _split_key(m.group(2))
            if m.group(1) == "[[":
                k = arrays.get(path, 0)
                arrays[path] = k + 1
                lines.setdefault(path, lineno)
                path = (*path, k)
            table = path
            lines.setdefault(table, lineno)
            continue
        m = _KEY_LINE.match(line)
        if not m:
            continue
        path = table + _split_key(m.group(1))
        for k in range(len(table) + 1, len(path) + 1):  # a dotted key defines its prefixes too
            lines.setdefault(path[:k], lineno)
        rest = m.group(2)
        for quote in ('"""', "'''"):
            if rest.count(quote) % 2 == 1:
                in_string = quote
        if not in_string:
            _inline_keys(rest, path, lineno, lines)
    return lines


def show_key(path):
    """A key path as the user writes it: ``sampling.train.n``, ``validation[2].n`` (1-based)."""
    out = ""
    for p in path:
        if isinstance(p, int):
            out += f"[{p + 1}]"
        else:
            out += ("." if out else "") + (p if re.fullmatch(_BARE, p) else f'"{p}"')
    return out
