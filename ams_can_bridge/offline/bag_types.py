# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The message definitions of a bag's connections, as rosbags' Jazzy typestore gives them.

Building that typestore was 0.09 s of every conversion's start, for the four types written
here (bench/README.md, third pass): their definitions and RIHS01 hashes are kept here, what
``Writer.add_connection`` takes instead of a store. test_log2bag_bagout.py holds them equal
to the store's ``generate_msgdef``/``hash_rihs01`` (copy those again if rosbags changes them).
"""

_SEPARATOR = '=' * 80 + '\n'
# std_msgs/Header and the Time in it, as a message with a header lists them
_HEADER = (_SEPARATOR + 'MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n'
           + _SEPARATOR + 'MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n')

# message type -> (msgdef, RIHS01 hash)
MSGDEFS: dict[str, tuple[str, str]] = {
    'sensor_msgs/msg/BatteryState': (
        'uint8 POWER_SUPPLY_STATUS_UNKNOWN=0\n'
        'uint8 POWER_SUPPLY_STATUS_CHARGING=1\n'
        'uint8 POWER_SUPPLY_STATUS_DISCHARGING=2\n'
        'uint8 POWER_SUPPLY_STATUS_NOT_CHARGING=3\n'
        'uint8 POWER_SUPPLY_STATUS_FULL=4\n'
        'uint8 POWER_SUPPLY_HEALTH_UNKNOWN=0\n'
        'uint8 POWER_SUPPLY_HEALTH_GOOD=1\n'
        'uint8 POWER_SUPPLY_HEALTH_OVERHEAT=2\n'
        'uint8 POWER_SUPPLY_HEALTH_DEAD=3\n'
        'uint8 POWER_SUPPLY_HEALTH_OVERVOLTAGE=4\n'
        'uint8 POWER_SUPPLY_HEALTH_UNSPEC_FAILURE=5\n'
        'uint8 POWER_SUPPLY_HEALTH_COLD=6\n'
        'uint8 POWER_SUPPLY_HEALTH_WATCHDOG_TIMER_EXPIRE=7\n'
        'uint8 POWER_SUPPLY_HEALTH_SAFETY_TIMER_EXPIRE=8\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_UNKNOWN=0\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_NIMH=1\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_LION=2\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_LIPO=3\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_LIFE=4\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_NICD=5\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_LIMN=6\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_TERNARY=7\n'
        'uint8 POWER_SUPPLY_TECHNOLOGY_VRLA=8\n'
        'std_msgs/Header header\n'
        'float32 voltage\n'
        'float32 temperature\n'
        'float32 current\n'
        'float32 charge\n'
        'float32 capacity\n'
        'float32 design_capacity\n'
        'float32 percentage\n'
        'uint8 power_supply_status\n'
        'uint8 power_supply_health\n'
        'uint8 power_supply_technology\n'
        'bool present\n'
        'float32[] cell_voltage\n'
        'float32[] cell_temperature\n'
        'string location\n'
        'string serial_number\n'
        + _HEADER,
        'RIHS01_4bee5dfce981c98faa6828b868307a0a73f992ed0789f374ee96c8f840e69741'),
    'std_msgs/msg/Float32MultiArray': (
        'std_msgs/MultiArrayLayout layout\n'
        'float32[] data\n'
        '================================================================================\n'
        'MSG: std_msgs/MultiArrayLayout\n'
        'std_msgs/MultiArrayDimension[] dim\n'
        'uint32 data_offset\n'
        '================================================================================\n'
        'MSG: std_msgs/MultiArrayDimension\n'
        'string label\n'
        'uint32 size\n'
        'uint32 stride\n',
        'RIHS01_0599f6f85b4bfca379873a0b4375a0aca022156bd2d7021275d116ed1fa8bfe0'),
    'std_msgs/msg/Float32': (
        'float32 data\n',
        'RIHS01_7170d3d8f841f7be3172ce5f4f59f3a4d7f63b0447e8b33327601ad64d83d6e2'),
    'diagnostic_msgs/msg/DiagnosticArray': (
        'std_msgs/Header header\n'
        'diagnostic_msgs/DiagnosticStatus[] status\n'
        + _HEADER + _SEPARATOR
        + 'MSG: diagnostic_msgs/DiagnosticStatus\n'
        'byte OK=0\n'
        'byte WARN=1\n'
        'byte ERROR=2\n'
        'byte STALE=3\n'
        'byte level\n'
        'string name\n'
        'string message\n'
        'string hardware_id\n'
        'diagnostic_msgs/KeyValue[] values\n'
        '================================================================================\n'
        'MSG: diagnostic_msgs/KeyValue\n'
        'string key\n'
        'string value\n',
        'RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e'),
}
