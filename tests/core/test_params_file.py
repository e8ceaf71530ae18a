"""Tunables from YAML (`--params`): every field of core/params.py can be set, nested ones too; a bad file
names field and line and loads nothing."""

import dataclasses
import typing

import pytest
import yaml

from core import params
from core.params_file import FRACTIONS, POSITIVE, Tunables, load_params, parse_params
from core.yaml_validation import FileFormatError


def test_sections_override_only_what_they_name():
    t = parse_params("htmpc: {gamma: 0.5, delta_safe_m: 0.3}\nsim:\n  hand_camera: {range_m: 2.0}\n"
                     "sequencer: {nominal_speed_mps: 0.8}\nrobot: {arm_speed_radps: [1, 1, 1, 1, 1, 1]}\n")
    d = Tunables()
    assert (t.htmpc.gamma, t.htmpc.delta_safe_m, t.htmpc.N) == (0.5, 0.3, d.htmpc.N)
    assert t.sim.hand_camera.range_m == 2.0 and t.sim.base_camera == d.sim.base_camera
    assert t.sequencer.nominal_speed_mps == 0.8 and t.mapping == d.mapping
    assert t.robot.arm_speed_radps == (1.0,) * 6


def test_every_default_written_out_reads_back_equal(tmp_path):
    """Every tunable (all sections, nested camera parameters) is a key the file may set."""
    d = Tunables()
    path = tmp_path / "all.yaml"
    path.write_text(yaml.safe_dump({k: dataclasses.asdict(v) for k, v in d.sections().items()}), encoding="utf-8")
    assert load_params(path) == d


@pytest.mark.parametrize(("text", "field", "line", "says"), [
    ("htmpc:\n  gama: 0.5\n", "htmpc.gama", 2, "Extra inputs"),
    ("htmpc:\n  N: 2.5\n", "htmpc.N", 2, "integer"),
    ("sim:\n  hand_camera:\n    range_m: -1\n", "sim.hand_camera.range_m", 3, "greater than 0"),
    ("htmpc: {constraint: foo}\n", "htmpc.constraint", 1, "'cbf' or 'edf'"),
    ("mapping:\n  theta_stat: 1.5\n", "mapping.theta_stat", 2, "less than or equal to 1"),
    ("robot:\n  arm_speed_radps: [1, 1]\n", "robot.arm_speed_radps", 2, "at least 6"),
    ("htmpc:\n  dt_s: .nan\n", "htmpc.dt_s", 2, "finite"),
    ("sequencer:\n  inflation_m: -0.1\n", "sequencer.inflation_m", 2, "greater than or equal to 0"),
    ("cameras: {}\n", "cameras", 1, "Extra inputs"),
])
def test_bad_values_name_field_and_line(text, field, line, says):
    with pytest.raises(FileFormatError) as err:
        parse_params(text, "p.yaml")
    ((f, ln, msg),) = err.value.problems
    assert (f, ln) == (field, line) and says in msg


def test_bound_tables_name_real_fields():
    classes = {c.__name__: c for c in vars(params).values() if dataclasses.is_dataclass(c)}
    for key in [*POSITIVE, *FRACTIONS]:
        cls, name = key.split(".")
        assert name in {f.name for f in dataclasses.fields(classes[cls])}, key


def test_every_string_tunable_is_a_closed_choice_its_default_is_in():
    """Option sets are Literals, so a params file is checked against them (no free-form strings)."""
    for cls in (c for c in vars(params).values() if dataclasses.is_dataclass(c)):
        for name, hint in typing.get_type_hints(cls).items():
            assert hint is not str, f"{cls.__name__}.{name} is a bare str"
            if typing.get_origin(hint) is typing.Literal:
                assert getattr(cls(), name) in typing.get_args(hint)
