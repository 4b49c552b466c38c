"""The simulation's options (``SimOptions``): their sections, their dict form and overrides by
dotted names, e.g. ``tapping.peak_force_N=4``."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .errors import DesignError
from .fe import ELEMENTS_3D, NewtonOptions
from .geometry import DEFAULT_MESH, DEFAULT_MESH_3D, MeshOptions, MeshOptions3D
from .protocols import PlateOptions, TappingOptions, ValidityOptions, WedgeOptions

__all__ = [
    "ELEMENTS_3D",
    "INCLINATION_RANGE_DEG",
    "MODELS",
    "ModelOptions",
    "SimOptions",
    "apply_overrides",
    "option_names",
    "options_from_dict",
    "parse_override",
]


#: The models a design can be simulated with: the paper's plane-strain section ("2d",
#: ``sim.fe.fe2d``) and the pad swept along the finger ("3d", ``sim.fe.fe3d``,
#: ``sim.geometry.pad``).
MODELS = ("2d", "3d")

#: The 3D model's plate inclinations (deg, ``ModelOptions.inclination_deg``): 0 (the human
#: targets' angle) to 45 (the largest of Serina et al.'s angles the pad represents; 90 loads the
#: end of the pad, where the symmetric profile is least like a finger): docs/fingertip_3d.md,
#: "Should the 3D model have a finger-inclination option?".
INCLINATION_RANGE_DEG = (0.0, 45.0)


@dataclass(frozen=True)
class ModelOptions:
    """Which model simulates the design (``--model``, ``--set model.dimension=3d``), and in
    3D the inclination of the finger to the plate (``--set model.inclination_deg=30``).

    ``inclination_deg`` = t tilts the plate of the tapping and plate protocols about the
    cross-finger axis x, its outward normal (0, cos t, sin t): it is lowest towards z > 0, the
    fingertip's end of the pad, and first touches the pad where the pad's normal is that
    (``sim.geometry.mesh3d.first_touch_mm``). The model is then the half pad x >= 0
    (``sim.geometry.mesh3d.half_pad_mesh``); forces and displacements are read along the
    plate's normal, the contact patch in its plane. 0 (the default) is the quarter model,
    unchanged, and is left out of the dict form (``SimOptions.as_dict``) so that records keep
    their keys. 3D only; the wedge is not inclined (``sim.simulate`` refuses it).

    ``element`` (``--set model.element=q2p1``): the 3D model's element (``ELEMENTS_3D``); left
    out of the dict form when it is "q2", so that the records made before it existed keep
    their keys. 3D only."""

    dimension: str = "2d"
    inclination_deg: float = 0.0
    element: str = "q2"

    def __post_init__(self) -> None:
        if self.dimension not in MODELS:
            raise DesignError(
                "model.dimension", f"must be one of {', '.join(MODELS)}, got {self.dimension!r}"
            )
        lo, hi = INCLINATION_RANGE_DEG
        t = self.inclination_deg
        if isinstance(t, bool) or not isinstance(t, int | float) or not lo <= t <= hi:
            raise DesignError(
                "model.inclination_deg", f"must be in [{lo:g}, {hi:g}] degrees, got {t!r}"
            )
        if t != 0.0 and self.dimension != "3d":
            raise DesignError(
                "model.inclination_deg",
                f"applies to the 3d model only, not to --model {self.dimension}",
            )
        if self.element not in ELEMENTS_3D:
            raise DesignError(
                "model.element",
                f"must be one of {', '.join(ELEMENTS_3D)}, got {self.element!r}",
            )
        if self.element != "q2" and self.dimension != "3d":
            raise DesignError(
                "model.element", f"applies to the 3d model only, not to --model {self.dimension}"
            )


#: The sections a model does not read, left out of its dict form (``SimOptions.as_dict``)
_UNREAD = {"2d": ("model", "mesh3d"), "3d": ("mesh",)}


@dataclass(frozen=True)
class SimOptions:
    """Numerical and protocol options; the defaults are the converged reference settings."""

    mesh: MeshOptions = DEFAULT_MESH
    newton: NewtonOptions = NewtonOptions()
    tapping: TappingOptions = TappingOptions()
    plate: PlateOptions = PlateOptions()
    wedge: WedgeOptions = WedgeOptions()
    validity: ValidityOptions = ValidityOptions()
    model: ModelOptions = ModelOptions()
    mesh3d: MeshOptions3D = DEFAULT_MESH_3D

    @property
    def dimension(self) -> str:
        """ "2d" or "3d" (``model.dimension``)."""
        return self.model.dimension

    def as_dict(self) -> dict[str, Any]:
        """The options' dict form (config.json, the key of a stored result) with the sections
        the model reads: a 2D run's without ``model`` and ``mesh3d`` (so 2D results keep the
        keys they were stored under before the 3D model existed), a 3D run's without the 2D
        ``mesh``. ``options_from_dict`` gives the defaults to the sections left out. The 3D
        model's ``model.inclination_deg`` is there only when it is not 0 (so the records of
        the flat plate keep the keys they had before the option existed), and the wedge's
        band (``mesh3d.edge_h_mm``, ``edge_grading``) only when it is on, and the 3D model's stall
        rule (``newton.stall_rule_3d``) only when it is not the default."""
        d = dataclasses.asdict(self)
        if "model" in d and d["model"]["inclination_deg"] == 0.0:
            del d["model"]["inclination_deg"]
        if "model" in d and d["model"]["element"] == "q2":
            del d["model"]["element"]
        # the wedge's band, only when on (its grading means nothing without it): the records
        # made before it existed keep their keys
        if "mesh3d" in d and d["mesh3d"]["edge_h_mm"] == 0.0:
            del d["mesh3d"]["edge_h_mm"], d["mesh3d"]["edge_grading"]
        # the 3D model's stall rule, only when not its default (the records made before the
        # option existed keep their keys; their solver version tells the rule they ran)
        if d["newton"]["stall_rule_3d"] == NewtonOptions.stall_rule_3d:
            del d["newton"]["stall_rule_3d"]
        return {k: v for k, v in d.items() if k not in _UNREAD[self.dimension]}

    def with_steps_scaled(self, factor: float) -> SimOptions:
        """Every step count multiplied by ``factor`` (time-step convergence studies)."""
        tap, plate, wedge = self.tapping, self.plate, self.wedge
        return dataclasses.replace(
            self,
            tapping=tap.with_steps_scaled(factor),
            plate=dataclasses.replace(plate, steps=max(2, round(plate.steps * factor))),
            wedge=dataclasses.replace(
                wedge,
                ramp_steps=max(2, round(wedge.ramp_steps * factor)),
                hold_steps=max(4, round(wedge.hold_steps * factor)),
            ),
        )

    def without_validity_stop(self) -> SimOptions:
        """Every protocol runs to its end, beyond the validity limits too
        (``ValidityOptions.stop_at_violation`` off): the extrapolated numbers of an invalid
        design, for studies that show them and for ``--allow-untrusted``."""
        return dataclasses.replace(
            self, validity=dataclasses.replace(self.validity, stop_at_violation=False)
        )

    def with_mesh_refined(self, factor: float) -> SimOptions:
        """Every element size divided by ``factor`` (mesh convergence studies), of the mesh
        the model uses."""
        if self.dimension == "3d":
            return dataclasses.replace(self, mesh3d=self.mesh3d.refined(factor))
        return dataclasses.replace(self, mesh=self.mesh.refined(factor))


def options_from_dict(d: dict[str, Any]) -> SimOptions:
    """SimOptions from their ``dataclasses.asdict`` form (as a sweep's config.json holds).

    A section missing from ``d`` (a config written before the section existed, e.g. the shipped
    sweep's before ``validity``) keeps its defaults. A ``mesh3d`` section without the wedge's
    band (``edge_h_mm``) has it off: ``as_dict`` leaves the band out when it is off, and the
    3D configs written before it existed have none, while the default mesh has one."""
    base = SimOptions()
    options = dataclasses.replace(
        base,
        **{
            f.name: dataclasses.replace(getattr(base, f.name), **d.get(f.name, {}))
            for f in dataclasses.fields(base)
        },
    )
    if "mesh3d" in d and "edge_h_mm" not in d["mesh3d"]:  # the band off (``as_dict``)
        options = dataclasses.replace(options, mesh3d=options.mesh3d.without_edge())
    return options


def option_names(options: SimOptions | None = None) -> list[str]:
    """Every overridable option as ``section.field``."""
    options = SimOptions() if options is None else options
    return [
        f"{section.name}.{f.name}"
        for section in dataclasses.fields(options)
        for f in dataclasses.fields(getattr(options, section.name))
    ]


def parse_override(text: str) -> tuple[str, str]:
    """``"section.field=value"`` -> (name, raw value)."""
    if "=" not in text:
        raise DesignError("--set", f"expected section.field=value, got {text!r}")
    name, value = text.split("=", 1)
    return name.strip(), value.strip()


def apply_overrides(options: SimOptions, overrides: Mapping[str, Any]) -> SimOptions:
    """A copy of ``options`` with the dotted names replaced (values parsed to the field's type).

    Unknown names, values of the wrong type and non-positive step counts or sizes raise
    ``DesignError`` naming the option.
    """
    sections: dict[str, dict[str, Any]] = {}
    for name, raw in overrides.items():
        section, _, field = name.partition(".")
        if section not in {f.name for f in dataclasses.fields(options)}:
            raise DesignError(name, f"unknown option; known: {', '.join(option_names(options))}")
        current = getattr(options, section)
        if field not in {f.name for f in dataclasses.fields(current)}:
            raise DesignError(name, f"unknown option; known: {', '.join(option_names(options))}")
        sections.setdefault(section, {})[field] = _parse(name, raw, getattr(current, field))
    out = options
    for section, changes in sorted(sections.items(), key=lambda item: item[0] != "model"):
        try:  # the model first: which options apply depends on it
            value = dataclasses.replace(getattr(out, section), **changes)
        except DesignError:  # names its own field (ModelOptions)
            raise
        except ValueError as exc:  # a section's own range check (e.g. MeshOptions3D)
            name = f"{section}.{next(iter(changes))}"
            prefix = f"{type(getattr(out, section)).__name__}."
            raise DesignError(name, str(exc).removeprefix(prefix)) from None
        out = dataclasses.replace(out, **{section: value})
    for name in overrides:
        section, _, field = name.partition(".")
        other = _ONLY_IN.get((section, field)) or _ONLY_IN.get((section, "*"))
        if other is not None and other != out.dimension:
            raise DesignError(
                name, f"applies to the {other} model only, not to --model {out.dimension}"
            )
    return out


#: Options that only one model reads (section, field or "*"): naming them for the other model
#: is an error, not a silent no-op. The 3D pad's forces have no out-of-plane length.
_ONLY_IN = {
    ("mesh", "*"): "2d",
    ("mesh3d", "*"): "3d",
    ("tapping", "length_mm"): "2d",
    ("plate", "length_mm"): "2d",
    ("wedge", "length_mm"): "2d",
    ("model", "inclination_deg"): "3d",
    ("newton", "stall_rule_3d"): "3d",
}


def _parse(name: str, raw: Any, default: Any) -> Any:
    # a None default is an optional number (validity.max_compressive_log_strain: None, each
    # layer's own limit): a value given overrides it
    kind = float if default is None else type(default)
    try:
        if kind is bool:
            if isinstance(raw, bool):
                return raw
            if str(raw).lower() in {"true", "1", "yes"}:
                return True
            if str(raw).lower() in {"false", "0", "no"}:
                return False
            raise ValueError
        value = kind(raw)
    except (TypeError, ValueError):
        raise DesignError(name, f"must be a {kind.__name__}, got {raw!r}") from None
    if kind in (int, float):
        if not math.isfinite(value):
            raise DesignError(name, f"must be finite, got {raw!r}")
        if name == "model.inclination_deg":  # an angle: ModelOptions checks its range
            return value
        # 0: off (mesh3d.edge_h_mm: no band along the wedge's edge, the default)
        zero_ok = name.endswith(("settle_tol", "residual_tol", "stall_window", "edge_h_mm"))
        if value < 0 or (value == 0 and not zero_ok):
            raise DesignError(name, f"must be {'>=' if zero_ok else '>'} 0, got {raw!r}")
    return value
