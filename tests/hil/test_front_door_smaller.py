"""Issue 25's smaller front-door findings: `calibrate --write` through a symbolic link, `hil
identify` given one run twice or a directory for --figure, and a robot description that is no
URDF."""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import pytest

from hil.cli import main
from hil.cli.calibrate import write_keeping_backup
from hil.config import (
    ConfigError,
    default_config_text,
    load_config,
    parse_config,
)
from hil.experiments import IdentifyExperiment
from hil.identify import ChirpExcitation
from hil.session import Session, Setup
from hil.vocabulary import ControllerChoice, ControllerKind
from hil.wiring import check_devices

OLD, NEW = "old = 1\n", "new = 2\n"


def test_a_write_through_a_symbolic_link_replaces_the_file_it_names(tmp_path: Path) -> None:
    """It replaced the link by a file and left the target as it was, saying "updated"."""
    real = tmp_path / "configs" / "testbed.toml"
    real.parent.mkdir()
    real.write_text(OLD)
    link = tmp_path / "testbed.toml"
    link.symlink_to(real)
    backup = write_keeping_backup(link, NEW)
    assert link.is_symlink() and link.resolve() == real
    assert real.read_text() == NEW and backup.read_text() == OLD
    assert backup.parent == real.parent  # beside the file, not the link


SHORT = IdentifyExperiment(
    name="identify",
    title="identification, shortened",
    excitation=ChirpExcitation(
        fit_sweep_duration_s=6.0, validation_sweep_duration_s=3.0, settle_duration_s=1.0
    ),
)


@pytest.fixture(scope="module")
def identification_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("identify")
    session = Session(load_config(), Setup.IN_PROCESS, out_root=root, plots=False, quiet=True)
    result = session.run_one(SHORT, ControllerChoice(ControllerKind.PID), print_result=False)
    assert result.ok, result.ending
    return result.out_dir


def test_one_run_given_twice_is_refused(identification_run: Path, tmp_path: Path, capsys) -> None:
    """Twice, it was fitted as two independent runs: the 95 % interval narrowed by ~sqrt 2."""
    copy = tmp_path / "copy"
    shutil.copytree(identification_run, copy)
    for twice in (
        [identification_run, identification_run],
        [identification_run, identification_run / ".." / identification_run.name],
        [identification_run, copy],
    ):
        assert main(["identify", *map(str, twice)]) == 2
        assert "the same run as" in capsys.readouterr().err


def test_a_figure_directory_gets_the_figure_inside_it(
    identification_run: Path, tmp_path: Path, capsys
) -> None:
    """It wrote DIR.png beside the directory."""
    figures = tmp_path / "figures"
    figures.mkdir()
    assert main(["identify", str(identification_run), "--json", "--figure", str(figures)]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert Path(result["figure"]) == figures / "identification.png"
    assert (figures / "identification.png").read_bytes()[:4] == b"\x89PNG"
    assert not (tmp_path / "figures.png").exists()


def test_the_identified_fragment_is_within_the_configurations_ranges(
    identification_run: Path, capsys
) -> None:
    """What `hil identify` fits pastes into a configuration the ranges admit."""
    assert main(["identify", str(identification_run)]) == 0
    capsys.readouterr()
    fragment = tomllib.loads((identification_run / "identification.toml").read_text())
    config = load_config().changed("model", **fragment["model"])
    check_devices(config.changed("emulator", **fragment["emulator"]))


@pytest.mark.parametrize(
    ("content", "said"),
    [
        ("hello, not XML\n", "is not a URDF: not XML"),
        ("<html><body/></html>\n", "is not a URDF: its root element is <html>"),
        ('<robot name="x"><link name="a"/><link name="a"/></robot>\n', "link 'a' is not unique"),
    ],
)
def test_a_description_that_is_no_urdf_is_said_naming_the_file(
    content: str, said: str, tmp_path: Path, capfd
) -> None:
    """The URDF parser printed its own raw error on the terminal ("Error: ... at line 103 in
    /project/urdfdom/..."); now one message says which file and what is wrong."""
    urdf = tmp_path / "legs.urdf"
    urdf.write_text(content)
    text = default_config_text("dyros-jet").replace(
        'description = "dyros_jet.urdf"', f'description = "{urdf}"', 1
    )
    config = parse_config(text, source="jet.toml")
    with pytest.raises(ConfigError, match=rf"jet.toml \[model\] description: .*{said}"):
        check_devices(config)
    captured = capfd.readouterr()
    assert "Error:" not in captured.err + captured.out
