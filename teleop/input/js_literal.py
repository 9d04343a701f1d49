"""A minimal reader of JavaScript object literals: the data of a (minified) ES module as JSON.

IWER captures (:mod:`teleop.input.iwer`) are ES modules ``export {capture}`` whose value is a
JavaScript object literal: JSON plus unquoted keys, single-quoted strings, ``!0``/``!1``,
``void 0``, trailing commas and bare ``5.``/``.5`` numbers. :func:`parse_js_literal` rewrites
only those bits into JSON (strings are matched whole, so nothing inside them changes) and decodes
the rest with :mod:`json`; a syntax error is reported at its line and column in the original
file. Not a JavaScript parser: code other than the literal is never evaluated.
"""

from __future__ import annotations

import bisect
import json
import re
from typing import Any

from sim.errors import DexaugError

__all__ = ["CaptureError", "parse_js_literal"]


class CaptureError(DexaugError):
    """A capture file cannot be read or parsed; the message names the file and position."""


# Only the JSON-incompatible bits of a minified JS literal are matched (strings are matched
# whole so nothing inside them is touched); everything else is already JSON and passes through.
# The leading look-ahead lets the scanner skip digits (the bulk of a capture) without trying
# the alternatives: a 2.5 MB capture converts in about 0.3 s instead of 1 s.
_JS_TOKEN = re.compile(r"""
  (?=['"/!A-Za-z_$,{.])
  (?:
    (?P<str>'(?:[^'\\\n]|\\.)*'|"(?:[^"\\\n]|\\.)*")
  | (?P<comment>//[^\n]*|/\*.*?\*/)
  | (?P<bang>!\s*[01](?![\w.]))
  | (?P<void>(?<![\w$.])void\s+0(?![\w.]))
  | (?P<key>(?<![\w$.])[A-Za-z_$][\w$]*(?=\s*:))
  | (?P<ident>(?<![\w$.])[A-Za-z_$][\w$]*)
  | (?P<numkey>[{,]\s*\d+(?=\s*:))
  | (?P<trail>,(?=\s*[\]}]))
  | (?P<dotend>(?<=\d)\.(?!\d))
  | (?P<dotstart>(?<!\d)\.(?=\d))
  )
""", re.S | re.X)
_JS_IDENT_VALUES = {"true": "true", "false": "false", "null": "null", "undefined": "null",
                    "NaN": "NaN", "Infinity": "Infinity"}
_JS_ESCAPE = re.compile(r"\\(u\{[0-9a-fA-F]+\}|u[0-9a-fA-F]{4}|x[0-9a-fA-F]{2}|\r\n|.)", re.S)
_JS_SIMPLE_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "b": "\b", "f": "\f", "v": "\v",
                      "0": "\0", "\n": "", "\r": "", "\r\n": ""}


def _js_unescape(m: re.Match[str]) -> str:
    e = m.group(1)
    if e[0] in "ux" and len(e) > 1:
        return chr(int(e[2:-1] if e[1] == "{" else e[1:], 16))
    return _JS_SIMPLE_ESCAPES.get(e, e)


def _js_string_to_json(token: str) -> str:
    """A JS string literal (either quote) as a JSON string literal."""
    body = token[1:-1]
    if "\\" in body:
        body = _JS_ESCAPE.sub(_js_unescape, body)
    # ensure_ascii keeps lone surrogates (from "\ud83d\ude00") escaped, so JSON re-pairs them
    return json.dumps(body)


class _JsToJson:
    """Rewrites the JS-only syntax of a data literal into JSON and remembers where it changed
    lengths, so a JSON error position can be reported in the original file."""

    def __init__(self) -> None:
        self.conv_ends: list[int] = []
        self.deltas: list[int] = []
        self._delta = 0

    def _replace(self, m: re.Match[str]) -> str:
        kind, tok = m.lastgroup, m.group()
        if kind == "str":
            out = tok if tok[0] == '"' and "\\" not in tok else _js_string_to_json(tok)
        elif kind == "comment":
            out = " "
        elif kind == "bang":
            out = "true" if tok[-1] == "0" else "false"
        elif kind == "void":
            out = "null"
        elif kind == "key":
            out = f'"{tok}"'
        elif kind == "ident":
            out = _JS_IDENT_VALUES.get(tok, tok)  # unknown names stay; JSON reports them
        elif kind == "numkey":
            digits = tok.lstrip("{,").lstrip()
            out = f'{tok[: len(tok) - len(digits)]}"{digits}"'
        elif kind == "dotend":  # "5." → "5.0"
            out = ".0"
        elif kind == "dotstart":  # ".5" → "0.5"
            out = "0."
        else:  # trailing comma
            out = ""
        if len(out) != len(tok):
            conv_start = m.start() + self._delta
            self._delta += len(out) - len(tok)
            self.conv_ends.append(conv_start + len(out))
            self.deltas.append(self._delta)
        return out

    def convert(self, text: str) -> str:
        return _JS_TOKEN.sub(self._replace, text)

    def source_pos(self, conv_pos: int) -> int:
        """Position in the original text of position ``conv_pos`` of the converted text."""
        k = bisect.bisect_right(self.conv_ends, conv_pos)
        return conv_pos - (self.deltas[k - 1] if k else 0)


def _literal_start(text: str, name: str) -> int:
    """Offset of the object literal exported as ``name`` (``export{a as capture}`` →
    ``var a=…``; or ``capture=…``; or ``export default …``; or a bare JSON file)."""
    candidates = []
    for m in re.finditer(r"export\s*\{([^}]*)\}", text):
        for spec in m.group(1).split(","):
            words = spec.split()
            if words and words[-1] == name:
                candidates.append(words[0])
    candidates.append(name)
    for local in candidates:
        assigned = re.search(rf"(?<![\w$.]){re.escape(local)}\s*=(?![=>])\s*", text)
        if assigned:
            return assigned.end()
    m_default = re.search(r"export\s+default\s*", text)
    if m_default:
        return m_default.end()
    stripped = len(text) - len(text.lstrip())
    if text[stripped:stripped + 1] in ("{", "["):
        return stripped
    raise ValueError(f"no `{name}` object literal found (expected `export {{{name}}}` with "
                     f"`var <x> = {{...}}`, `{name} = {{...}}` or a JSON object)")


def parse_js_literal(text: str, name: str = "capture", *, path: str = "<string>") -> Any:
    """The JSON-like value of the object literal exported as ``name`` from a (minified) ES
    module; :class:`CaptureError` names ``path``, line, column and the text there on failure."""
    try:
        start = _literal_start(text, name)
    except ValueError as exc:
        raise CaptureError(f"{path}: {exc}") from None
    conv = _JsToJson()
    converted = conv.convert(text[start:])
    try:
        value, _ = json.JSONDecoder().raw_decode(converted)
    except json.JSONDecodeError as exc:
        pos = start + conv.source_pos(exc.pos)
        line = text.count("\n", 0, pos) + 1
        col = pos - (text.rfind("\n", 0, pos) + 1) + 1
        near = text[max(0, pos - 30):pos + 30].replace("\n", "\\n")
        raise CaptureError(f"{path}: cannot parse the `{name}` literal at line {line}, column "
                           f"{col} (char {pos}): {exc.msg}; near {near!r}") from None
    return value
