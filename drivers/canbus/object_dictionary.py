"""The CANopen objects the CAN sensor driver reads or writes, with their standard data types.

A programmatic `canopen.ObjectDictionary` rather than a vendor EDS: the driver relies only on
objects that CiA 301, CiA 406 (encoders) and CiA 404 (measuring devices) define, so it works
with any conforming node without its EDS. Sources: CiA 301 communication objects; CiA 406
objects as in the BEI, ifm RM9000 and Lika IF55 manuals; CiA 404 analogue-input objects as in
the esd CAN-CBX-THERMO manual (0x6131, 0x6132, 0x7130, 0x9130).
"""

from __future__ import annotations

from canopen.objectdictionary import ObjectDictionary, ODArray, ODRecord, ODVariable, datatypes

TPDO_COMMUNICATION_BASE = 0x1800  # + TPDO number - 1
TPDO_MAPPING_BASE = 0x1A00


def _variable(name: str, index: int, subindex: int, data_type: int, access: str) -> ODVariable:
    variable = ODVariable(name, index, subindex)
    variable.data_type = data_type
    variable.access_type = access
    return variable


def _compound(compound: ODRecord | ODArray, members: list[ODVariable]) -> ODRecord | ODArray:
    for member in members:
        compound.add_member(member)
    return compound


def sensor_object_dictionary() -> ObjectDictionary:
    """Objects of CiA 301/406/404 that `LinkEncoderReader` uses."""
    od = ObjectDictionary()
    od.add_object(_variable("Device type", 0x1000, 0, datatypes.UNSIGNED32, "ro"))
    od.add_object(_variable("Error register", 0x1001, 0, datatypes.UNSIGNED8, "ro"))
    od.add_object(
        _variable("Manufacturer device name", 0x1008, 0, datatypes.VISIBLE_STRING, "const")
    )
    od.add_object(_variable("Producer heartbeat time", 0x1017, 0, datatypes.UNSIGNED16, "rw"))
    identity = ODRecord("Identity object", 0x1018)
    od.add_object(
        _compound(
            identity,
            [
                _variable("Highest sub-index supported", 0x1018, 0, datatypes.UNSIGNED8, "ro"),
                _variable("Vendor-ID", 0x1018, 1, datatypes.UNSIGNED32, "ro"),
                _variable("Product code", 0x1018, 2, datatypes.UNSIGNED32, "ro"),
                _variable("Revision number", 0x1018, 3, datatypes.UNSIGNED32, "ro"),
                _variable("Serial number", 0x1018, 4, datatypes.UNSIGNED32, "ro"),
            ],
        )
    )
    for number in range(1, 5):
        communication = TPDO_COMMUNICATION_BASE + number - 1
        mapping = TPDO_MAPPING_BASE + number - 1
        od.add_object(
            _compound(
                ODRecord(f"TPDO{number} communication parameter", communication),
                [
                    _variable(
                        "Highest sub-index supported", communication, 0, datatypes.UNSIGNED8, "ro"
                    ),
                    _variable("COB-ID used by TPDO", communication, 1, datatypes.UNSIGNED32, "rw"),
                    _variable("Transmission type", communication, 2, datatypes.UNSIGNED8, "rw"),
                    _variable("Event timer", communication, 5, datatypes.UNSIGNED16, "rw"),
                ],
            )
        )
        od.add_object(
            _compound(
                ODRecord(f"TPDO{number} mapping parameter", mapping),
                [_variable("Number of mapped objects", mapping, 0, datatypes.UNSIGNED8, "rw")]
                + [
                    _variable(f"Mapped object {entry}", mapping, entry, datatypes.UNSIGNED32, "rw")
                    for entry in range(1, 9)
                ],
            )
        )
    # CiA 406 encoder.
    od.add_object(_variable("Operating parameters", 0x6000, 0, datatypes.UNSIGNED16, "rw"))
    od.add_object(
        _variable("Measuring units per revolution", 0x6001, 0, datatypes.UNSIGNED32, "rw")
    )
    od.add_object(_variable("Position value", 0x6004, 0, datatypes.INTEGER32, "ro"))
    # CiA 404 measuring device, analogue input channels 1..6 (one for the contact force
    # sensor, six for a force/torque sensor; 0x7130 is the 16-bit, 0x9130 the 32-bit PV).
    for index, name, data_type in (
        (0x6131, "AI physical unit PV", datatypes.UNSIGNED32),
        (0x6132, "AI decimal digits PV", datatypes.UNSIGNED8),
        (0x7130, "AI input PV (16 bit)", datatypes.INTEGER16),
        (0x9130, "AI input PV", datatypes.INTEGER32),
    ):
        od.add_object(
            _compound(
                ODArray(name, index),
                [_variable("Number of entries", index, 0, datatypes.UNSIGNED8, "ro")]
                + [
                    _variable(f"{name} {channel}", index, channel, data_type, "ro")
                    for channel in range(1, 7)
                ],
            )
        )
    return od
