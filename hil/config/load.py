"""Reading a configuration file, and changing it from the command line, through one validation.

`load_config(path)` reads TOML and validates it against `hil.config.schema`; command-line
options that change a value (`--kdist`, `--seed`, ...) go through `Config.changed(...)`, the same
validation, so a value is refused the same way wherever it comes from. An error names the file
(or the option), the key as written, the value and what is allowed.
"""

from __future__ import annotations

import os
import stat
import tomllib
import xml.etree.ElementTree as ElementTree
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import PrivateAttr, ValidationError

from hil.config.ranges import figure_range
from hil.config.schema import ConfigFile
from hil.vocabulary import Robot


def builtin_config_name(robot: Robot) -> str:
    """The file of a robot's built-in configuration in hil/data: its name with _ for -."""
    return f"{robot.value.replace('-', '_')}.toml"


DEFAULT_CONFIG_NAME = builtin_config_name(Robot.TESTBED)
# The configurations shipped with hil, by robot (`hil config --robot NAME` prints them).
BUILT_IN_CONFIGS = {str(robot): builtin_config_name(robot) for robot in Robot}


class ConfigError(ValueError):
    """A configuration file or option is malformed or inconsistent. The message says where."""


class Config(ConfigFile):
    """A validated configuration and where it came from (`source`)."""

    _source: str = PrivateAttr(default="<built-in>")

    @property
    def source(self) -> str:
        return self._source

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(joint.name for joint in self.joints)

    def changed(self, section: str, *, option: str | None = None, **values: Any) -> Config:
        """A copy with these keys of one section changed, validated like the file.

        option: the command-line option the values come from, named in the error.
        """
        raw = self.model_dump(by_alias=True, exclude_unset=False)
        if section not in raw or not isinstance(raw[section], dict):
            raise KeyError(f"no section [{section}]")
        raw[section] = {**raw[section], **values}
        return _validated(raw, self.source, error_prefix=option)

    def replaced(self, **sections: Any) -> Config:
        """A copy with whole sections replaced (pydantic models or plain tables), validated."""
        raw = self.model_dump(by_alias=True)
        for name, value in sections.items():
            key = "joint" if name == "joints" else name
            if isinstance(value, list | tuple):
                raw[key] = [
                    v.model_dump(warnings=False) if hasattr(v, "model_dump") else v for v in value
                ]
            else:
                raw[key] = (
                    value.model_dump(warnings=False) if hasattr(value, "model_dump") else value
                )
        return _validated(raw, self.source)

    def record(self) -> dict[str, Any]:
        """The configuration as plain JSON data, for a run's meta.json."""
        return {"source": self.source, **self.model_dump(mode="json", by_alias=True)}


def _robot(robot: Robot | str) -> Robot:
    try:
        return Robot(robot)
    except ValueError:
        raise ConfigError(
            f"no built-in configuration for robot {robot!r}: {sorted(BUILT_IN_CONFIGS)}"
        ) from None


def default_config_text(robot: Robot | str = Robot.TESTBED) -> str:
    """The configuration shipped for `robot` (see BUILT_IN_CONFIGS)."""
    name = builtin_config_name(_robot(robot))
    return resources.files("hil").joinpath("data", name).read_text()


def robot_of(config: Config) -> Robot:
    """The robot this configuration describes (`[model] robot`): what an experiment is
    checked against."""
    return config.model.robot


def load_config(path: str | Path | None = None, *, robot: Robot | str = Robot.TESTBED) -> Config:
    """Read and check a configuration file; None reads the built-in one of `robot`."""
    if path is None:
        name = builtin_config_name(_robot(robot))
        return parse_config(default_config_text(robot), source=f"<built-in {name}>")
    path = Path(path)
    return parse_config(read_text_file(path, "configuration file"), source=str(path))


# A configuration file is a few kB (the humanoid's, every key commented: 17 kB); more than this
# is no configuration (`/dev/zero` would be read until memory ran out).
MAX_CONFIG_BYTES = 1 << 20


def read_text_file(path: Path, what: str, max_bytes: int = MAX_CONFIG_BYTES) -> str:
    """A regular text file of at most `max_bytes`, read without blocking on what is not one
    (a FIFO would wait for a writer for ever, a device never ends): ConfigError otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror}") from exc
    with os.fdopen(fd, "rb") as f:
        info = os.fstat(f.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError(f"{path}: not a regular file (a {what} is a file of text)")
        if info.st_size > max_bytes:
            raise ConfigError(
                f"{path}: {info.st_size} bytes, more than a {what} holds "
                f"(at most {max_bytes} bytes)"
            )
        try:
            data = f.read(max_bytes + 1)
        except OSError as exc:
            raise ConfigError(f"cannot read {what} {path}: {exc.strerror}") from exc
    if len(data) > max_bytes:  # it grew while it was read
        raise ConfigError(f"{path}: more than a {what} holds (at most {max_bytes} bytes)")
    try:
        return data.decode()
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not a text file: {exc}") from exc


def config_from_record(record: dict[str, Any]) -> Config:
    """A configuration back from `Config.record()` (a run's meta.json), validated like a file."""
    raw = {key: value for key, value in record.items() if key != "source"}
    return _validated(raw, str(record.get("source", "<meta.json>")))


def parse_config(text: str, source: str = "<string>") -> Config:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from exc
    _refuse_moved_keys(raw, source)
    return _validated(raw, source)


def _validated(raw: dict[str, Any], source: str, *, error_prefix: str | None = None) -> Config:
    """Validate; errors name `error_prefix` (a command-line option) or the source file."""
    try:
        config = Config.model_validate(raw)
    except ValidationError as exc:
        raise ConfigError(_describe(exc, raw, source, option=error_prefix)) from None
    config._source = source
    return config


# Keys that moved in the split into buses / joints / model: say where they went.
_MOVED_JOINT_KEYS = (
    "stiffness_nm_per_rad",
    "damping_nms_per_rad",
    "servo_gain_per_s",
    "link_inertia_kg_m2",
    "gravity_moment_kg_m",
)


def _refuse_moved_keys(raw: dict[str, Any], source: str) -> None:
    joints = raw.get("joint")
    if not isinstance(joints, list):
        return
    for number, joint in enumerate(joints, start=1):
        if isinstance(joint, dict):
            moved = [key for key in _MOVED_JOINT_KEYS if key in joint]
            if moved:
                raise ConfigError(
                    f"{source} [[joint]] #{number}: {moved} belong to the robot model now: "
                    "move them to the [model] section (per joint: [model.joint.NAME]); "
                    "`hil config` prints the current layout"
                )


_RANGE_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


def _describe(
    exc: ValidationError, raw: dict[str, Any], source: str, option: str | None = None
) -> str:
    lines = []
    for error in exc.errors(include_url=False):
        where = f"{source} {_location(error['loc'], raw)}" if option is None else option
        message = error["msg"]
        if message.startswith("Value error, "):
            message = message[len("Value error, ") :]
        if error["type"] in _RANGE_ERRORS:
            allowed = figure_range(ConfigFile, tuple(error["loc"]))
            if allowed is not None:
                message = f"{message}: its physical range is {allowed}"
        shown = ""
        if error["type"] not in ("missing", "extra_forbidden") and "input" in error:
            value = error["input"]
            if not isinstance(value, dict | list):
                shown = f" (got {value!r})"
        if error["type"] == "extra_forbidden":
            message = "unknown key"
        lines.append(f"{where}: {message}{shown}")
    return "; ".join(lines)


def _location(loc: tuple[Any, ...], raw: dict[str, Any]) -> str:
    """('joint', 0, 'dynamixel_id') -> "[[joint]] #1 'link' dynamixel_id"."""
    if not loc:
        return "(file)"
    head, rest = loc[0], list(loc[1:])
    if head in ("joint", "dynamixel", "can") and rest and isinstance(rest[0], int):
        index = rest.pop(0)
        table = raw.get(head)
        name = ""
        if isinstance(table, list) and index < len(table) and isinstance(table[index], dict):
            name = f" {table[index].get('name')!r}" if "name" in table[index] else ""
        where = f"[[{head}]] #{index + 1}{name}"
    else:
        where = f"[{head}]"
    keys = ".".join(str(part) for part in rest)
    return f"{where} {keys}".strip()


def robot_description_text(config: Config) -> str:
    """The robot's URDF ([model] description): a path, or the name of one shipped with the
    package (hil/data/robots/NAME or NAME.urdf)."""
    name = config.model.description
    where = f"{config.source} [model] description"
    if name is None:
        raise ConfigError(f"{where}: missing (a URDF)")
    path = Path(name).expanduser()
    if path.exists():
        return _urdf(read_text_file(path, "URDF", MAX_URDF_BYTES), f"{where}: {path}")
    shipped = resources.files("hil").joinpath("data", "robots")
    for candidate in (name, f"{name}.urdf"):
        resource = shipped.joinpath(candidate)
        if resource.is_file():
            return _urdf(resource.read_text(), f"{where}: {name}")
    known = sorted(p.name for p in shipped.iterdir() if p.name.endswith(".urdf"))
    raise ConfigError(
        f"{config.source} [model] description: {name!r} is neither a file nor one of the "
        f"robots shipped with hil ({known})"
    )


# DYROS-JET's URDF is 60 kB; a robot description of more than this is no URDF.
MAX_URDF_BYTES = 16 << 20


def _urdf(text: str, where: str) -> str:
    """`text` if it is a URDF (XML whose root is <robot>): said here, naming the file, rather
    than by the URDF parser's own message on the terminal."""
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise ConfigError(f"{where} is not a URDF: not XML ({exc})") from None
    if root.tag != "robot":
        raise ConfigError(
            f"{where} is not a URDF: its root element is <{root.tag}>, a URDF's is <robot>"
        )
    return text
