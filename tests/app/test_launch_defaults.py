"""The app starts with localization on (`app/launch_defaults.py`), and a `--params` file is read over that: it
can turn localization off, and a file about other sections leaves it on."""

from pathlib import Path

from app.cli import _config, build_parser
from app.launch_defaults import launch_tunables
from core.params import LocalizationParams


def _run_config(tmp_path: Path, params: str | None):
    argv = ["run", "--headless", "--map", "object"]
    if params is not None:
        path = tmp_path / "params.yaml"
        path.write_text(params, encoding="utf-8")
        argv += ["--params", str(path)]
    return _config(build_parser().parse_args(argv))


def test_the_app_starts_localized_where_the_library_does_not(tmp_path: Path) -> None:
    assert not LocalizationParams().enabled  # the experiments' and benchmarks' configuration
    config = _run_config(tmp_path, None)
    assert config.localization.enabled
    assert config.localization == launch_tunables().localization


def test_a_params_file_turns_it_off_or_leaves_it_on(tmp_path: Path) -> None:
    assert not _run_config(tmp_path, "localization: {enabled: false}\n").localization.enabled
    other = _run_config(tmp_path, "htmpc: {gamma: 0.5}\nlocalization: {rate_hz: 2.0}\n")
    assert other.localization.enabled and other.localization.rate_hz == 2.0 and other.htmpc.gamma == 0.5
