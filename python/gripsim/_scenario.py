"""Scenarios: read from a file, a TOML text or a dict, with the CLI's ``--set`` overrides."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from . import _gripsim


def _set_text(value) -> str:
    """A Python value as the value text of a ``--set KEY=VALUE``: a string as it is (the
    CLI reads it as TOML, or as a bare string), numbers, booleans and lists as TOML."""
    if isinstance(value, str):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{value!r} is not a finite number")
    if isinstance(value, (bool, int, float, list, tuple)):
        return json.dumps(value)
    raise TypeError(f"cannot set a scenario value of type {type(value).__name__}: {value!r}")


class Scenario:
    """A scenario (planar or 3D, as its ``dimension`` says) and the ``--set`` overrides given
    to it. It is read, and each override checked, when it is made or changed; a bad one
    raises :class:`gripsim.ScenarioError` naming the file, key and value."""

    def __init__(self, text: str, file: str = "<scenario>", dir: str | os.PathLike = ".",
                 sets: list[str] | None = None):
        self.text = text
        self.file = file
        self.dir = str(dir)
        self.sets = list(sets or [])
        self._info = _gripsim.validate(self.text, self.file, self.dir, self.sets)

    @classmethod
    def load(cls, path: str | os.PathLike, sets: list[str] | None = None) -> "Scenario":
        """The scenario in the TOML file ``path`` (a 3D mesh is found beside it)."""
        path = Path(path)
        try:
            text = path.read_text()
        except OSError as e:
            from ._errors import ScenarioError

            raise ScenarioError(f"{path}: cannot read the scenario: {e}", file=str(path),
                                message=f"cannot read the scenario: {e}") from None
        return cls(text, str(path), path.parent, sets)

    @classmethod
    def from_toml(cls, text: str, name: str = "<toml>") -> "Scenario":
        """The scenario in the TOML ``text`` (``name`` is its name in messages)."""
        return cls(text, name)

    @classmethod
    def from_dict(cls, d: dict, name: str = "<dict>") -> "Scenario":
        """The scenario whose sections are the dict ``d`` (as the TOML file would read)."""
        return cls(_gripsim.toml_from_json(json.dumps(d)), name)

    def set(self, key: str, value) -> "Scenario":
        """Override ``key`` (a dotted path: ``"rod.0.E"``, ``"solve.dt"``) with ``value``, by
        the rules of the CLI's ``--set key=value``. Checked at once; returns the scenario."""
        sets = self.sets + [f"{key}={_set_text(value)}"]
        self._info = _gripsim.validate(self.text, self.file, self.dir, sets)
        self.sets = sets
        return self

    def validate(self) -> dict:
        """Read the scenario again as the CLI's ``gripsim validate`` does; returns its
        ``dimension``, ``name`` and ``warnings``, or raises :class:`gripsim.ScenarioError`."""
        self._info = _gripsim.validate(self.text, self.file, self.dir, self.sets)
        return dict(self._info)

    @property
    def name(self) -> str:
        """The scenario's ``name``."""
        return self._info["name"]

    @property
    def dimension(self) -> int:
        """2 (planar) or 3."""
        return self._info["dimension"]

    @property
    def warnings(self) -> list[str]:
        """What the reader accepted but a person should know."""
        return list(self._info["warnings"])

    def __repr__(self) -> str:
        sets = f", sets={self.sets!r}" if self.sets else ""
        return f"Scenario({self.name!r}, dimension={self.dimension}, file={self.file!r}{sets})"
