"""Versions of what a run depended on, for meta.json (a log should say what produced it)."""

from __future__ import annotations

from importlib import metadata

PACKAGES = (
    "flexjoint-hil",
    "numpy",
    "scipy",
    "mujoco-core",
    "dynamixel-sdk",
    "python-can",
    "canopen",
    "pin",
    "pydantic",
)


def package_versions() -> dict[str, str]:
    versions = {}
    for name in PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions
