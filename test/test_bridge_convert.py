# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ros/convert.py: its message objects read off the wire as ones built field by field."""
import math

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge import reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level
from ams_can_bridge.ros import convert

NAN = math.nan
REPORTS = [
    BatteryReport(),  # nothing known: NaN everywhere, no stamp
    BatteryReport(stamp=1_700_000_000.123456789, voltage=403.2, temperature=31.5,
                  current=-12.25, charge=55.5, capacity=60.0, design_capacity=62.0,
                  percentage=0.925, power_supply_status=2, power_supply_health=1,
                  power_supply_technology=2, present=True,
                  cell_voltage=[3.6 + k / 1000 for k in range(140)] + [NAN],
                  cell_temperature=[25, 26.5, NAN], location='rear', serial_number='S/N 7'),
    BatteryReport(stamp=5.999999999, voltage=-0.0, cell_voltage=[1e39, -1e-45],
                  present=False),
]


def wire(msg) -> str:
    """Return what a subscriber gets, as text (NaN equals NaN there)."""
    return repr(deserialize_message(serialize_message(msg), type(msg)))


def by_constructor(report: BatteryReport, frame_id: str, fallback: float) -> BatteryState:
    """Build the message the way convert did before: constructors and property setters."""
    fields = reports.battery_fields(report)
    msg = BatteryState(**fields)
    sec, nanosec = reports.stamp_parts(reports.report_stamp(report, fallback))
    msg.header.stamp = Time(sec=sec, nanosec=nanosec)
    msg.header.frame_id = frame_id
    return msg


@pytest.mark.parametrize('report', REPORTS)
def test_battery_state_serializes_like_the_constructor(report):
    fast = convert.battery_state(report, 'pack_link', 1_800_000_000.5)
    slow = by_constructor(report, 'pack_link', 1_800_000_000.5)
    assert wire(fast) == wire(slow)
    assert type(fast.header.stamp) is Time and type(fast.cell_voltage[0:0]) is type(
        slow.cell_voltage[0:0])
    # the message stays an ordinary one: fields read and set as usual
    fast.header.stamp = convert.stamp_msg(2.5)
    assert (fast.header.stamp.sec, fast.header.stamp.nanosec) == (2, 500_000_000)


def test_multi_array_serializes_like_the_constructor():
    fast = convert.multi_array(2, 3, [1.0, 2.5, NAN, 4, 5, -6.25], ('module', 'cell'))
    slow = Float32MultiArray()
    slow.layout = convert._layout(2, 3, ('module', 'cell'))
    slow.data = [1.0, 2.5, NAN, 4.0, 5.0, -6.25]
    assert wire(fast) == wire(slow)
    assert [(d.label, d.size, d.stride) for d in fast.layout.dim] == [
        ('module', 2, 6), ('cell', 3, 3)]


def test_diagnostic_status_serializes_like_the_constructor():
    report = DiagnosticReport(Level.WARN, 'two things', {'a': '1', 'b key': 'x y', 'c': ''})
    fast = convert.diagnostic_status(report, 'bridge: ams', 'slcan:/dev/x')
    slow = DiagnosticStatus(level=b'\x01', name='bridge: ams', message='two things',
                            hardware_id='slcan:/dev/x',
                            values=[KeyValue(key=k, value=v) for k, v in report.values.items()])
    assert wire(fast) == wire(slow)
    assert fast.values == slow.values


def test_stamp_msg():
    assert wire(convert.stamp_msg(12.25)) == wire(Time(sec=12, nanosec=250_000_000))
    assert (convert.stamp_msg(NAN).sec, convert.stamp_msg(-1.0).nanosec) == (0, 0)


def test_negative_zero_is_published_as_zero_in_every_float():
    """Issue 18.7: -0.0 (a sign flip of 0) reads as 0.0 in scalars, cells and arrays."""
    from ams_can_bridge.ros import diag_cdr
    z = -0.0
    report = BatteryReport(stamp=1.0, voltage=z, temperature=z, current=z, charge=z,
                           capacity=z, design_capacity=z, percentage=z, present=True,
                           cell_voltage=[3.6, z, NAN, z], cell_temperature=[z, 20.0])

    def positive(value):
        return math.isnan(value) or math.copysign(1.0, value) > 0

    for msg in (convert.battery_state(report, 'f'),
                deserialize_message(diag_cdr.battery_state(report, 'f'), BatteryState)):
        msg = deserialize_message(serialize_message(msg), BatteryState)
        scalars = [msg.voltage, msg.temperature, msg.current, msg.charge, msg.capacity,
                   msg.design_capacity, msg.percentage]
        assert all(positive(v) for v in scalars + list(msg.cell_voltage)
                   + list(msg.cell_temperature)), msg
        assert list(msg.cell_voltage)[:2] == [pytest.approx(3.6), 0.0]
    data = [z, 1.5, z, NAN, -2.0]
    for msg in (convert.multi_array(1, 5, data),
                deserialize_message(diag_cdr.multi_array(1, 5, data), Float32MultiArray)):
        msg = deserialize_message(serialize_message(msg), Float32MultiArray)
        assert all(positive(v) for v in list(msg.data)[:4])
        assert list(msg.data)[4] == -2.0


def test_a_node_logger_made_again_forwards_each_record_once():
    # configure runs again after a cleanup (lifecycle): the node's stdlib logger is made
    # again under the same name and must not print every line twice
    import logging

    from ams_can_bridge.ros.convert import stdlib_logger

    class RosLogger:
        def __init__(self) -> None:
            self.lines: list[str] = []

        def warning(self, text: str) -> None:
            self.lines.append(text)

    first, second = RosLogger(), RosLogger()
    stdlib_logger('test_bridge_convert.again', first, logging.DEBUG)
    logger = stdlib_logger('test_bridge_convert.again', second)
    logger.warning('bus lost')
    assert second.lines == ['bus lost'] and first.lines == []
    assert logger.level == logging.DEBUG and not logger.propagate
