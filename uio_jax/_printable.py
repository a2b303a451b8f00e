"""Text from model files made safe for a terminal: one helper, :func:`printable`.

A model file from someone else can carry names, units or messages with terminal escape
sequences (``\\x1b[2J`` clears the screen), carriage returns or newlines (a forged report or
table line), or bidirectional overrides (text shown in another order than it is). Every
place that prints text taken from a model (the report's text, the batch table, the Monte
Carlo summary, the command line's error line) passes it through :func:`printable`: such
characters are shown as escapes (``\\x1b``, ``\\n``, ``\\u202e``), visible and inert; the
data itself (JSON, ``Report.system_name``) keeps the original text.
"""

import re

#: Control characters (C0, DEL, C1) and the invisible bidirectional formatting characters.
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(match) -> str:
    c = match.group()
    if c in _NAMED:
        return _NAMED[c]
    code = ord(c)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text, keep: str = "") -> str:
    """``text`` (any object, through ``str``) with every control character and
    bidirectional override replaced by a visible escape (``\\x1b``, ``\\n``, ``\\u202e``),
    except the characters in ``keep`` (``"\\n"`` for a multi-line text whose lines this
    program made)."""
    text = str(text)
    if not _UNSAFE.search(text):
        return text
    return _UNSAFE.sub(lambda m: m.group() if m.group() in keep else _escape(m), text)
