"""Controller plug-ins: found where the user says, checked against the contract with a message
that names the file and what is wrong (exit 2, nothing opened), run through the same loop as the
paper's four, named by the record, and stopped by the supervisor when they misbehave."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from hil.cli import main
from hil.controllers import BUILT_IN, ControllerLoadError, resolve
from hil.controllers.registry import controller_params
from hil.vocabulary import ControllerChoice, ControllerKind

GOOD = """
import numpy as np
from hil import Controller, ControllerParams, ControlInput

class Follow(Controller):
    class Params(ControllerParams):
        gain: float = 1.0
    term_names = ("offset_rad",)
    needs_link_angle = False

    def start(self, state: ControlInput) -> None:
        self.offset = np.zeros(self.setup.n_joints)

    def step(self, state: ControlInput) -> np.ndarray:
        return state.reference_rad * self.params.gain + self.offset

    def terms(self):
        return {"offset_rad": self.offset}
"""


def _plugin(tmp_path: Path, body: str, name: str = "plugin.py") -> Path:
    path = tmp_path / name
    path.write_text(textwrap.dedent(body))
    return path


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_the_papers_four_are_registry_entries() -> None:
    for kind in ControllerKind:
        assert kind.value in BUILT_IN
        ref = resolve(kind.value)
        assert ref.paper is kind and ref.built_in
        assert ref.uses_kdist == (kind is ControllerKind.GC_LQR_DOB)


def test_a_plugin_file_resolves_with_its_traits(tmp_path: Path) -> None:
    ref = resolve(f"{_plugin(tmp_path, GOOD)}:Follow")
    assert ref.name == "Follow" and ref.paper is None and not ref.built_in
    assert ref.spec.startswith("file:") and ref.spec.endswith(":Follow")
    assert not ref.needs_link_angle and not ref.uses_kdist
    choice = ControllerChoice(ref)
    assert choice.label == "Follow" and choice.dir_name == "follow"
    assert controller_params(ref, choice, {"gain": 2.0}).gain == 2.0  # type: ignore[attr-defined]


def test_a_module_plugin_resolves(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _plugin(tmp_path, GOOD, "my_controllers.py")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert resolve("my_controllers:Follow").spec == "my_controllers:Follow"


@pytest.mark.parametrize(
    ("body", "spec_class", "said"),
    [
        (GOOD, "Nope", "has no Nope (its classes: Follow)"),
        ("class Follow:\n    pass\n", "Follow", "is not a controller"),
        (
            "from hil import Controller\nclass Follow(Controller):\n    def start(self, s):\n"
            "        pass\n",
            "Follow",
            "does not define step()",
        ),
        ("import numpy\n\nx = 1 / 0\n", "Follow", "(line 3) failed: ZeroDivisionError"),
        ("def broken(:\n", "Follow", "(line 1) failed: SyntaxError"),
        (GOOD.replace('("offset_rad",)', '"offset_rad"'), "Follow", "term_names must be a tuple"),
    ],
)
def test_what_breaks_the_contract_is_said(
    tmp_path: Path, body: str, spec_class: str, said: str
) -> None:
    path = _plugin(tmp_path, body, f"p{abs(hash(body)) % 10**8}.py")
    with pytest.raises(ControllerLoadError) as caught:
        resolve(f"{path}:{spec_class}")
    assert said in str(caught.value) and str(path.name) in str(caught.value)


def test_unknown_names_and_missing_files_are_said(tmp_path: Path) -> None:
    with pytest.raises(ControllerLoadError, match="unknown controller 'lqg'"):
        resolve("lqg")
    with pytest.raises(ControllerLoadError, match="no such file"):
        resolve(f"{tmp_path / 'absent.py'}:X")


def test_parameters_are_checked_by_the_plugins_schema(tmp_path: Path) -> None:
    ref = resolve(f"{_plugin(tmp_path, GOOD)}:Follow")
    choice = ControllerChoice(ref)
    with pytest.raises(ControllerLoadError, match=r"\[controller.params\] gain"):
        controller_params(ref, choice, {"gain": "two"})
    with pytest.raises(ControllerLoadError, match=r"\[controller.params\] extra"):
        controller_params(ref, choice, {"extra": 1})
    with pytest.raises(ControllerLoadError, match="takes its parameters from"):
        controller_params(resolve("pid"), ControllerChoice("pid"), {"gain": 1})


def test_a_plugin_runs_through_the_loop_and_the_record_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = f"{_plugin(tmp_path, GOOD)}:Follow"
    out = tmp_path / "runs"
    argv = ["run", "impact", "--controller", spec, "--param", "gain=1.0", "--duration", "1"]
    assert _exit_code([*argv, "--out", str(out), "--no-plots", "--json"]) == 0
    (run,) = out.iterdir()
    assert run.name.endswith("-impact-follow")
    meta = json.loads((run / "meta.json").read_text())
    assert meta["controller"] == "Follow" and meta["controller_spec"].endswith(":Follow")
    assert meta["controller_params"] == {"gain": 1.0}
    summary = json.loads((run / "summary.json").read_text())
    assert summary["controller"] == "Follow" and summary["termination"] == "completed"
    header = (run / "log.csv").read_text().splitlines()[0].split(",")
    assert "offset_rad" in header and "uc_rad" not in header
    line = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert line["controller"] == "Follow"


@pytest.mark.parametrize(
    ("step", "said"),
    [
        ("return state.reference_rad[:0]", "step() returned shape (0,), not (1,)"),
        ("return state.reference_rad * np.nan", "not finite"),
        ("raise RuntimeError('bug')", "step raised RuntimeError: bug"),
        ("import time; time.sleep(0.02); return state.reference_rad", "longer than the loop"),
    ],
)
def test_a_plugin_that_fails_at_rest_is_refused_before_anything_opens(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], step: str, said: str
) -> None:
    body = GOOD.replace(
        "return state.reference_rad * self.params.gain + self.offset",
        step.replace("; ", "\n        "),
    )
    spec = f"{_plugin(tmp_path, body)}:Follow"
    out = tmp_path / "runs"
    assert _exit_code(["run", "impact", "--controller", spec, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert said in err and "plugin.py" in err, err
    assert not out.exists() or not any(out.iterdir())


def test_a_plugin_that_raises_mid_run_is_stopped_with_torque_off(tmp_path: Path) -> None:
    body = GOOD.replace(
        "return state.reference_rad * self.params.gain + self.offset",
        "if state.time_s > 0.5:\n            raise KeyError('late bug')\n"
        "        return state.reference_rad",
    )
    spec = f"{_plugin(tmp_path, body)}:Follow"
    out = tmp_path / "runs"
    argv = ["run", "impact", "--controller", spec, "--duration", "1", "--no-plots"]
    assert _exit_code([*argv, "--out", str(out)]) == 1
    (run,) = out.iterdir()
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    kinds = [e["kind"] for e in events]
    assert "controller_traceback" in kinds and "controller_fault" in kinds
    trace = next(e for e in events if e["kind"] == "controller_traceback")["message"]
    assert "KeyError: 'late bug'" in trace and "plugin.py" in trace
    fault = next(e for e in events if e["kind"] == "controller_fault")
    assert fault["action"] == "torque_off" and 0.5 < fault["time_s"] < 0.6
    torque_off = [e for e in events if e["kind"] == "torque_off"]
    assert torque_off and torque_off[0]["time_s"] <= fault["time_s"] + 0.011
    summary = json.loads((run / "summary.json").read_text())
    assert summary["termination"] == "safety stop: controller_fault (torque_off)"
    log = (run / "log.csv").read_text().splitlines()
    header = log[0].split(",")
    torque = header.index("torque_enabled")
    assert log[-1].split(",")[torque] == "0"
