"""A schema key: its kind, range or choices and default, and the one check that applies it (`Key.check`).

The sidecar's tables (bake/sidecar_schema.py) and a material's fields (core/material_schema.py, which
the viewer's panel uses too, so it lives in core) are tables of `Key`s: one rule and one message
wording, "WHERE KEY must be ALLOWED, not VALUE".
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glint.core.errors import GlintError

KINDS = ("whole", "number", "bool", "choice", "string", "vec3", "rgb", "power2")


@dataclass(frozen=True)
class Key:
    """One sidecar key: `kind` (KINDS), the range lo..hi (`above`/`below`: that end excluded) or
    the `choices`, and the `default` (None: none, or given elsewhere)."""

    kind: str
    lo: float | None = None
    hi: float | None = None
    above: bool = False
    below: bool = False
    choices: tuple = ()
    default: object = None

    def allowed(self) -> str:
        """What the key takes, in words: 'a whole number from 0 to 64', 'a number above 0'."""
        if self.kind == "bool":
            return "true or false"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices)
        if self.kind == "string":
            return "a string"
        if self.kind == "power2":
            return f"a power of two from {_num(self.lo)} to {_num(self.hi)}"
        noun = {"whole": "a whole number", "number": "a number", "vec3": "a list of 3 numbers",
                "rgb": "a number or a list of 3 numbers (RGB)"}[self.kind]
        low = None if self.lo is None else f"above {_num(self.lo)}" if self.above else f"from {_num(self.lo)}"
        high = None if self.hi is None else f"below {_num(self.hi)}" if self.below else f"to {_num(self.hi)}"
        if low and high:
            return f"{noun} {low} {'and ' if self.above or self.below else ''}{high}"
        if low:
            return f"{noun} {low if self.above else f'of at least {_num(self.lo)}'}"
        return f"{noun} {high}" if high else noun

    def check(self, value, where: str, key: str):
        """`value` checked and converted (int, float, bool, str, or an (3,) array for vec3 and rgb);
        a one-line GlintError "{where} {key} must be ..., not VALUE" otherwise. `key` "": `where`
        names the value alone (a command-line option)."""
        ok = {"choice": lambda v: isinstance(v, str) and v in self.choices,
              "bool": lambda v: isinstance(v, bool), "string": lambda v: isinstance(v, str),
              "vec3": lambda v: isinstance(v, list) and len(v) == 3 and all(map(self._in_range, v)),
              "rgb": lambda v: (self._in_range(v) if _is_number(v)
                                else isinstance(v, list) and len(v) == 3 and all(map(self._in_range, v)))
              }.get(self.kind, self._in_range)(value)
        if not ok:
            raise GlintError(" ".join(filter(None, (where, key, "must be"))) + f" {self.allowed()}, not {value!r}")
        if self.kind in ("vec3", "rgb"):
            return np.array([value] * 3 if _is_number(value) else value, np.float64)
        if self.kind in ("whole", "power2"):
            return int(value)
        return float(value) if self.kind == "number" else value

    def _in_range(self, v) -> bool:
        if not _is_number(v) or not math.isfinite(v):
            return False
        if self.kind in ("whole", "power2") and not float(v).is_integer():
            return False
        if self.kind == "power2" and int(v) & (int(v) - 1):
            return False
        lo_ok = self.lo is None or (v > self.lo if self.above else v >= self.lo)
        hi_ok = self.hi is None or (v < self.hi if self.below else v <= self.hi)
        return lo_ok and hi_ok


def _num(x) -> str:
    """A bound as written: 4294967295, 0.5 (not 4.29497e+09)."""
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)
