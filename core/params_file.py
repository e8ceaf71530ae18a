"""Tunables from a YAML file (`--params FILE.yaml`): any field of the dataclasses in `core/params.py`,
nested ones included, overridden by section; every other value keeps its default.

    htmpc: {gamma: 0.5, delta_safe_m: 0.3}
    sim:
      hand_camera: {range_m: 2.0}
    sequencer: {nominal_speed_mps: 0.8}

The file is checked by the machinery of task files (`core.yaml_validation`): an unknown section or key, a
value of the wrong type, a negative length or a zero rate is refused with its field and line, and nothing
is loaded. A section's schema is built from its dataclass, so a tunable added to `core/params.py` can be
set from a file at once.
"""

from __future__ import annotations

import dataclasses
import typing
from functools import cache
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, create_model

from core.params import HTMPCParams, LocalizationParams, MappingParams, RobotParams, SequencerParams, SimParams
from core.yaml_validation import load_yaml_file, load_yaml_model


@dataclasses.dataclass(frozen=True)
class Tunables:
    """One value of every parameter object of the method (defaults, or a file's overrides)."""

    robot: RobotParams = dataclasses.field(default_factory=RobotParams)
    sim: SimParams = dataclasses.field(default_factory=SimParams)
    htmpc: HTMPCParams = dataclasses.field(default_factory=HTMPCParams)
    mapping: MappingParams = dataclasses.field(default_factory=MappingParams)
    sequencer: SequencerParams = dataclasses.field(default_factory=SequencerParams)
    localization: LocalizationParams = dataclasses.field(default_factory=LocalizationParams)

    def sections(self) -> dict[str, Any]:
        """{section: parameter object}, e.g. as keyword arguments of the app's `RuntimeConfig`."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


POSITIVE = frozenset({
    "RobotParams.base_speed_mps", "RobotParams.base_yaw_rate_radps", "RobotParams.arm_speed_radps",
    "RobotParams.base_accel_mps2", "RobotParams.base_yaw_accel_radps2", "RobotParams.arm_accel_radps2",
    "RobotParams.base_xy_limit_m", "RobotParams.base_size_m",
    "CameraParams.width_px", "CameraParams.height_px", "CameraParams.fovy_deg", "CameraParams.range_m",
    "CameraParams.near_m", "CameraParams.rate_hz",
    "SimParams.timestep_s", "SimParams.room_half_size_m", "SimParams.floor_beyond_room_m", "SimParams.box_pool",
    "HTMPCParams.N", "HTMPCParams.dt_s", "HTMPCParams.gamma", "HTMPCParams.sqp_iters",
    "HTMPCParams.sqp_iters_on_switch", "HTMPCParams.control_rate_hz", "HTMPCParams.command_rate_hz",
    "HTMPCParams.control_max_rate_hz",
    "HTMPCParams.trust_region_m", "HTMPCParams.trust_region_rad", "HTMPCParams.solve_timeout_ms",
    "MappingParams.voxel_m", "MappingParams.range_m", "MappingParams.pixel_stride", "MappingParams.tau_m",
    "MappingParams.delta_max_m", "MappingParams.beta_cap", "MappingParams.edf_voxel_m",
    "MappingParams.theta_cutoff_m", "MappingParams.edf_window_m", "MappingParams.icp_max_iterations",
    "MappingParams.cost_sample_points", "MappingParams.carve_check_every",
    "SequencerParams.nominal_speed_mps", "SequencerParams.grid_cell_m", "SequencerParams.replan_period_s",
    "LocalizationParams.rate_hz", "LocalizationParams.stride_px", "LocalizationParams.source_voxel_m",
    "LocalizationParams.max_range_m", "LocalizationParams.max_iterations", "LocalizationParams.sigma_xy_m",
    "LocalizationParams.sigma_yaw_rad",
})
"""Fields that must be > 0 (a rate, a size, a count); other numbers whose default is ≥ 0 must stay ≥ 0."""
FRACTIONS = frozenset({"MappingParams.theta_stat", "MappingParams.split_fraction",
                       "MappingParams.duplicate_fraction", "MappingParams.clear_view_fraction"})
"""Fields within [0, 1]."""


def _bounded(key: str, annotation: Any, default: Any) -> Any:
    """The field's type with the bounds its meaning implies (see POSITIVE, FRACTIONS)."""
    number = annotation if annotation in (int, float) else None
    args = typing.get_args(annotation)
    element = args[0] if typing.get_origin(annotation) is tuple and args and args[0] in (int, float) else None
    base = number or element
    if base is None or isinstance(default, bool):
        return annotation
    values = default if element is not None else (default,)
    if key in FRACTIONS:
        bounded = typing.Annotated[base, Field(ge=0.0, le=1.0)]
    elif key in POSITIVE:
        bounded = typing.Annotated[base, Field(gt=0)]
    elif all(v >= 0 for v in values):
        bounded = typing.Annotated[base, Field(ge=0)]
    else:
        return annotation
    if element is None:
        return bounded
    if args[-1] is Ellipsis:  # as many values as the default has (one per arm joint, ...)
        return typing.Annotated[tuple[(bounded, ...)], Field(min_length=len(default), max_length=len(default))]
    return tuple[tuple(bounded for _ in args)]


@cache
def overrides_model(cls: type) -> type[BaseModel]:
    """A pydantic model of optional overrides for the dataclass `cls` (nested dataclasses recursively)."""
    hints = typing.get_type_hints(cls)
    fields = {}
    for f in dataclasses.fields(cls):
        annotation = hints[f.name]
        default = f.default if f.default_factory is dataclasses.MISSING else f.default_factory()
        if dataclasses.is_dataclass(annotation):
            annotation = overrides_model(annotation)
        else:
            annotation = _bounded(f"{cls.__name__}.{f.name}", annotation, default)
        fields[f.name] = (annotation | None, None)
    return create_model(f"{cls.__name__}Overrides", __config__=ConfigDict(extra="forbid", allow_inf_nan=False),
                        __doc__=cls.__doc__, **fields)


class ParamsFile(BaseModel):
    """A tunables file: sections named as `Tunables`' fields, each a partial override."""

    model_config = ConfigDict(extra="forbid")
    robot: overrides_model(RobotParams) | None = None  # type: ignore[valid-type]
    sim: overrides_model(SimParams) | None = None  # type: ignore[valid-type]
    htmpc: overrides_model(HTMPCParams) | None = None  # type: ignore[valid-type]
    mapping: overrides_model(MappingParams) | None = None  # type: ignore[valid-type]
    sequencer: overrides_model(SequencerParams) | None = None  # type: ignore[valid-type]
    localization: overrides_model(LocalizationParams) | None = None  # type: ignore[valid-type]

    def tunables(self, base: Tunables | None = None) -> Tunables:
        """`base` (default: the defaults) with this file's values."""
        base = base or Tunables()
        return Tunables(**{name: _apply(obj, getattr(self, name)) for name, obj in base.sections().items()})


def _apply(obj: Any, overrides: BaseModel | None) -> Any:
    if overrides is None:
        return obj
    changes = {}
    for name in overrides.model_fields_set:
        value = getattr(overrides, name)
        if value is None:
            continue
        changes[name] = _apply(getattr(obj, name), value) if isinstance(value, BaseModel) else value
    return dataclasses.replace(obj, **changes)


def parse_params(text: str, source: str = "<params>") -> Tunables:
    """Tunables from YAML text; `FileFormatError` names the field and line of every problem."""
    return load_yaml_model(text, ParamsFile, source).tunables()


def load_params(path: str | Path, base: Tunables | None = None) -> Tunables:
    """Tunables from a YAML file (see the module docstring) over `base` (default: the defaults)."""
    return load_yaml_file(path, ParamsFile).tunables(base)
