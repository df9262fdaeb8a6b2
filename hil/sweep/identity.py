"""What shapes every run of a sweep, and the output directory's record of it (sweep.json).

A run's result depends on more than its point: on the base configuration (its content, after
the spec's [base]; not the file's path, so the same file elsewhere is the same sweep), on the
robot's description when it is a URDF, on what the spec sets for every run (setup, model,
seed, duration, which keys each parameter sets) and on the code that runs it (the versions of
flexjoint-hil and of the libraries that compute a run: `hil.output.versions.PACKAGES`). These
make the sweep's identity; each run id hashes it with the run's point, experiment and
controller (hil/sweep/plan.py).

`claim(out_dir, identity)` writes sweep.json into a new output directory, or checks the one
there: a directory that holds another sweep's results is refused (`SweepMismatch`, the CLI's
exit 2), naming what differs, so that results of two configurations are never mixed or taken
for each other. The spec's points may change (a grid grown by a value resumes: the runs
already done keep their ids). Edits to the code within one package version (a development
checkout) are not seen: bump the version, or give another --out.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.config import Config, robot_description_text
from hil.output.strict_json import dumps
from hil.output.versions import package_versions
from hil.sweep.spec import SweepSpec
from hil.sweep.table import RESULTS_NAME

IDENTITY_NAME = "sweep.json"
FORMAT = 1
SHOWN_DIFFERENCES = 4  # at most this many differing keys are named


class SweepMismatch(ValueError):
    """The output directory holds the results of another sweep (the message says what
    differs)."""


def digest(data: Any, length: int) -> str:
    """A stable hash of JSON-like data (keys sorted)."""
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:length]


@dataclass(frozen=True)
class SweepIdentity:
    """Everything every run of a sweep shares that shapes its result (module docstring)."""

    parts: dict[str, Any]

    @property
    def digest(self) -> str:
        return digest(self.parts, 16)

    def record(self, spec_name: str) -> dict[str, Any]:
        return {"format": FORMAT, "spec": spec_name, "digest": self.digest, **self.parts}


def sweep_identity(spec: SweepSpec, base: Config) -> SweepIdentity:
    """The identity of `spec` run on `base` (the configuration with [base] applied)."""
    description = None
    if base.model.description is not None:
        description = hashlib.sha256(robot_description_text(base).encode()).hexdigest()
    content = {key: value for key, value in base.record().items() if key != "source"}
    return SweepIdentity(
        {
            "configuration": content,
            "robot_description_sha256": description,
            "runs": {
                "setup": str(spec.setup),
                "model": str(spec.model),
                "seed": spec.seed,
                "duration_s": spec.duration_s,
                "targets": {p.name: list(p.targets) for p in spec.parameters},
            },
            "packages": package_versions(),
        }
    )


def claim(out_dir: Path, identity: SweepIdentity, spec_name: str) -> None:
    """Record `identity` in `out_dir`, or check it against the one recorded there; raises
    SweepMismatch if the directory holds another sweep's results (module docstring). Call it
    with the directory locked (hil/sweep/lock.py)."""
    path = Path(out_dir) / IDENTITY_NAME
    if path.is_file():
        try:
            found = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise SweepMismatch(
                f"{path} cannot be read ({exc}): what shaped the results in {out_dir} is "
                "unknown; give another --out"
            ) from None
        if found.get("digest") == identity.digest:
            return
        differences = describe_differences(identity.parts, found)
        raise SweepMismatch(
            f"{out_dir} holds the results of another sweep ({found.get('spec', '?')}); "
            f"{'; '.join(differences)}: give another --out (or remove {out_dir} to start "
            "over)"
        )
    if _has_rows(Path(out_dir) / RESULTS_NAME):
        raise SweepMismatch(
            f"{out_dir} holds results without {IDENTITY_NAME} (written by an earlier hil, "
            "which did not record what shaped its runs): they cannot be told from another "
            "configuration's; give another --out"
        )
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(".json.tmp")
    temporary.write_text(dumps(identity.record(spec_name), indent=2) + "\n")
    os.replace(temporary, path)  # never a half-written sweep.json


def _has_rows(results: Path) -> bool:
    try:
        with open(results) as f:
            return len(f.readlines()[:2]) > 1
    except OSError:
        return False


def describe_differences(here: dict[str, Any], there: dict[str, Any]) -> list[str]:
    """What differs between this sweep's identity and the one found, in words."""
    described = []
    names = {
        "configuration": "the base configuration differs",
        "runs": "the spec's settings for every run differ",
        "packages": "the code differs",
    }
    for part, words in names.items():
        changed = _changed_keys(here.get(part), there.get(part))
        if changed:
            shown = ", ".join(
                f"{key} = {mine!r} here, {theirs!r} there"
                for key, mine, theirs in changed[:SHOWN_DIFFERENCES]
            )
            more = len(changed) - SHOWN_DIFFERENCES
            described.append(f"{words}: {shown}" + (f" (and {more} more)" if more > 0 else ""))
    if here.get("robot_description_sha256") != there.get("robot_description_sha256"):
        described.append("the robot's description (URDF) differs")
    if there.get("format") != FORMAT:
        described.append(f"its {IDENTITY_NAME} is of format {there.get('format')!r}")
    return described or ["what shaped its runs differs"]


def _changed_keys(here: Any, there: Any, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """(dotted key, value here, value there) for every leaf that differs."""
    if isinstance(here, dict) and isinstance(there, dict):
        changed = []
        for key in sorted(set(here) | set(there), key=str):
            name = f"{prefix}.{key}" if prefix else str(key)
            changed += _changed_keys(here.get(key, _ABSENT), there.get(key, _ABSENT), name)
        return changed
    if isinstance(here, list) and isinstance(there, list) and len(here) == len(there):
        changed = []
        for index, (mine, theirs) in enumerate(zip(here, there, strict=True)):
            changed += _changed_keys(mine, theirs, f"{prefix}[{index}]")
        return changed
    return [] if here == there else [(prefix or "(all)", here, there)]


class _Absent:
    """A key one side has and the other has not."""

    def __repr__(self) -> str:
        return "(absent)"


_ABSENT = _Absent()
