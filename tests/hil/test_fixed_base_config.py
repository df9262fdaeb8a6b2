"""A configuration for one's own fixed-base robot (`hil config --robot fixed-base`) is refused
before the first byte, exit 2 naming the key, where it is inconsistent with its URDF: a joint
the URDF lacks, an actuator whose continuous torque (or configured current cap) cannot hold the
joint's static load at the worst posture within the joint limits, two joints on one ID of a
chain, a tool link it lacks, a coupling a fixed base has not."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from hil.cli import main
from hil.config import default_config_text, load_config
from hil.robots.fixed_base.check import worst_static_load
from hil.robots.fixed_base.model import fixed_base_links

TEMPLATE = default_config_text("fixed-base")


def refused(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str) -> str:
    config = tmp_path / "robot.toml"
    config.write_text(text)
    out = tmp_path / "runs"
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["run", "hold", "--config", str(config), "--emulate", "--out", str(out)])
    assert code == 2
    assert not out.exists() or not list(out.iterdir()), "a run began"
    return capsys.readouterr().err


def test_the_template_runs_its_checks_clean(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    with contextlib.redirect_stdout(io.StringIO()) as text:
        assert main(["config", "--robot", "fixed-base"]) == 0
    assert text.getvalue() == TEMPLATE
    config.write_text(TEMPLATE)
    from hil.cli.common import checked_config

    checked_config(config)


def test_a_joint_the_urdf_lacks(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = TEMPLATE.replace('name = "elbow"', 'name = "elbo"', 1).replace(
        "[model.joint.elbow]", "[model.joint.elbo]"
    )
    err = refused(tmp_path, capsys, text)
    assert "[[joint]] #2 'elbo' name" in err and "no joints ['elbo']" in err


def test_an_actuator_too_weak_for_the_worst_posture(tmp_path: Path, capsys) -> None:
    # the shoulder carries 4.0 N m held horizontal; an M54-40-S250-R is rated 3.9 N m
    weak = TEMPLATE.replace('actuator = "H54-200-S500-R"', 'actuator = "M54-40-S250-R"')
    err = refused(tmp_path, capsys, weak)
    assert "[[joint]] #1 'shoulder' actuator: M54-40-S250-R's continuous torque (3.9 N m)" in err
    assert "4.0 N m at the worst posture" in err
    # within limits that keep the arm well away from horizontal, the same actuator holds it
    raised = weak.replace(
        "min_angle_rad = -1.2\nmax_angle_rad = 1.2", "min_angle_rad = 0.5\nmax_angle_rad = 1.2"
    )
    config = tmp_path / "raised.toml"
    config.write_text(raised)
    from hil.cli.common import checked_config

    checked_config(config)


def test_a_current_cap_too_small(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capped = TEMPLATE.replace(
        "encoder_node_id = 5\n", "encoder_node_id = 5\ntorque_limit_a = 0.5\n"
    )
    err = refused(tmp_path, capsys, capped)
    assert "'shoulder' actuator: H54-200-S500-R's torque_limit_a 0.5 A" in err


def test_two_joints_on_one_id(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(tmp_path, capsys, TEMPLATE.replace("dynamixel_id = 2", "dynamixel_id = 1"))
    assert "duplicate dynamixel_id on chain 'rs485': [1]" in err


def test_a_tool_and_a_coupling_it_has_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = refused(tmp_path, capsys, TEMPLATE.replace('tool_link = "tool"', 'tool_link = "hand"'))
    assert "[model] tool_link: 'hand' is no link" in err
    err = refused(
        tmp_path, capsys, TEMPLATE.replace('sm_coupling = "full"', 'sm_coupling = "closed-chain"')
    )
    assert "[model] sm_coupling" in err


def test_the_worst_static_load_is_found_at_the_worst_posture() -> None:
    """The search against the arm by hand: the shoulder's load is largest with both links
    horizontal, 9.81 (1.0 x 0.15 + 0.6 x 0.425) = 3.973 N m; within [0.5, 1.2] it is largest at
    0.5 with the elbow bent down to put the forearm horizontal."""
    model = fixed_base_links(load_config(robot="fixed-base")).fixed_base
    load, where = worst_static_load(model, 0, np.array([-1.2, -1.5]), np.array([1.2, 1.5]))
    assert load == pytest.approx(3.97305, rel=1e-6)
    np.testing.assert_allclose(where, (0.0, 0.0), atol=1e-4)
    load, where = worst_static_load(model, 0, np.array([0.5, -1.5]), np.array([1.2, 1.5]))
    expected = 9.81 * ((0.15 + 0.6 * 0.3) * np.cos(0.5) + 0.6 * 0.125)
    assert load == pytest.approx(expected, rel=1e-6)
    np.testing.assert_allclose(where, (0.5, -0.5), atol=1e-4)


def test_without_link_encoders_the_in_process_bus_refuses(tmp_path: Path) -> None:
    config = tmp_path / "stock.toml"
    config.write_text(TEMPLATE.replace("encoder_node_id = 6", "encoder_node_id = 0"))
    from hil.config import ConfigError
    from hil.wiring.in_process import in_process_bus

    with pytest.raises(ConfigError, match=r"\['elbow'\] have no link encoder"):
        in_process_bus(load_config(config))
