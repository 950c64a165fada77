"""The fit parameters: :class:`FitParams`, every setting of the Rust ``FitParams`` by name.

A :class:`FitParams` starts from a preset and overrides settings by name; the Rust core checks
every value (type and range) when the object is made, and the error names the setting and its
range. Each setting is an attribute whose documentation is the Rust struct's own (``help(fm.FitParams)``,
docs/parameters.md), grouped as in Rust.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from . import _foldmatch_rs as _core

#: The presets, in the order the docs list them.
PRESETS: tuple[str, ...] = ("default", "accurate", "fast", "paper", "tracking")

#: The groups of settings, as the Rust struct nests them: ``[(title, doc, [names])]``.
GROUPS: list[tuple[str, str, list[str]]] = [
    (g["title"], g["doc"], [s["name"] for s in g["settings"]]) for g in _core.param_reference()
]

#: Every setting's reference entry (``name``, ``type``, ``doc``, ``choices``), by name.
SETTINGS: dict[str, dict[str, Any]] = {s["name"]: s for g in _core.param_reference() for s in g["settings"]}


def _plain(value: Any) -> Any:
    """A NumPy scalar as the Python scalar it holds (the core reads Python values)."""
    return value.item() if isinstance(value, np.generic) else value


class FitParams(Mapping[str, Any]):
    """Every setting of a fit: a preset with settings overridden by name.

    >>> p = FitParams("paper", psi=0.1)
    >>> p.psi, p.two_way
    (0.1, 0.0)
    >>> p.replace(iterations=50).iterations
    50

    Parameters
    ----------
    preset : {"default", "accurate", "fast", "paper", "tracking"}
        Where the settings not given come from (see :func:`foldmatch_rs.fit`).
    **settings
        Settings by name (the attributes below; docs/parameters.md lists them with their
        ranges). An unknown name, a value of the wrong type or out of range raises
        :class:`~foldmatch_rs.errors.InvalidParameterError` naming the setting.

    A ``FitParams`` is immutable (``replace`` makes a changed copy), compares equal to one with
    the same settings, reads like a mapping (``p["psi"]``, ``dict(p)``) and pickles.
    """

    __slots__ = ("_values", "_preset")

    _values: dict[str, Any]
    _preset: str

    def __init__(self, preset: str = "default", /, **settings: Any) -> None:
        values = _core.fit_params(preset, {k: _plain(v) for k, v in settings.items()})
        object.__setattr__(self, "_values", values)
        object.__setattr__(self, "_preset", preset)

    @classmethod
    def preset(cls, name: str) -> FitParams:
        """The settings of the preset ``name``."""
        return cls(name)

    @classmethod
    def from_dict(cls, settings: Mapping[str, Any], preset: str = "default") -> FitParams:
        """``preset`` with ``settings`` (a mapping of names to values, e.g. a parsed
        ``--params`` JSON file or ``FitResult.params``) over it."""
        return cls(preset, **dict(settings))

    @property
    def preset_name(self) -> str:
        """The preset these settings started from."""
        return self._preset

    def replace(self, **settings: Any) -> FitParams:
        """A copy with ``settings`` changed (checked as in the constructor)."""
        return type(self)(self._preset, **{**self._values, **settings})

    def to_dict(self) -> dict[str, Any]:
        """Every setting, by name: the form of ``--params FILE`` and of the JSON report."""
        return dict(self._values)

    def changed(self) -> dict[str, Any]:
        """The settings that differ from the preset's."""
        base = _core.fit_params(self._preset, None)
        return {k: v for k, v in self._values.items() if base[k] != v}

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __getattr__(self, name: str) -> Any:
        # Reached only for names that are not attributes: an unknown setting.
        if name.startswith("_"):
            raise AttributeError(name)
        raise AttributeError(f"FitParams has no setting {name!r}; settings: {', '.join(SETTINGS)}")

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"FitParams is immutable: use .replace({name}=...)")

    def __eq__(self, other: object) -> bool:
        if isinstance(other, FitParams):
            return self._values == other._values
        if isinstance(other, Mapping):  # a dict of every setting, e.g. DEFAULT_PARAMS
            return self._values == dict(other)
        return NotImplemented

    def __hash__(self) -> int:
        return hash(tuple(self._values.items()))

    def __reduce__(self) -> tuple[Any, ...]:
        return (FitParams.from_dict, (self._values, self._preset))

    def __repr__(self) -> str:
        given = "".join(f", {k}={v!r}" for k, v in self.changed().items())
        return f"FitParams({self._preset!r}{given})"

    def __str__(self) -> str:
        """Every setting, by group; ``*`` marks those that differ from the preset."""
        changed = self.changed()
        lines = [repr(self)]
        for title, _, names in GROUPS:
            lines.append(f"  {title}:")
            for name in names:
                mark = "*" if name in changed else " "
                lines.append(f"   {mark}{name} = {self._values[name]!r}")
        return "\n".join(lines)


def _setting(name: str) -> property:
    entry = SETTINGS[name]
    doc = f"{entry['doc']}\n\nType: {entry['type']}."

    def get(self: FitParams) -> Any:
        return self._values[name]

    return property(get, doc=doc)


for _name in SETTINGS:
    setattr(FitParams, _name, _setting(_name))
del _name


__all__ = ["FitParams", "GROUPS", "PRESETS", "SETTINGS"]
