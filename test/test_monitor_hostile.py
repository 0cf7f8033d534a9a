# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A hostile ``/diagnostics`` publisher against ``monitor`` (issue 34, point 7).

A status naming a device that is no ROS name ended the monitor's executor thread (it then
showed "nothing from the bridge" forever), and escape sequences in a message reached the
terminal raw. Now such a status is skipped and counted, the view stays live, and every text
from a message is shown with its control characters escaped.
"""
from __future__ import annotations

import os
import re

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from ams_can_bridge.ros.demo_view import DeviceRow, printable, render, state_of, View
from ams_can_bridge.ros.spinner import Spinner
from ams_can_bridge.ros.watcher import BridgeWatcher
from helpers import ros_context, wait_for

CLEAR = '\x1b[2J\x1b[31m'


def status(prefix: str, device: str, message: str, state: str = '') -> DiagnosticStatus:
    values = [KeyValue(key='state', value=state)] if state else []
    return DiagnosticStatus(level=DiagnosticStatus.OK, name=f'{prefix}: {device}',
                            message=message, hardware_id='x', values=values)


def test_a_hostile_status_is_skipped_and_the_view_stays_live():
    namespace = f'hostile{os.getpid()}'
    prefix = f'{namespace}/ams_can_bridge'
    with ros_context() as context:
        watcher = BridgeWatcher(namespace, context=context)
        sender = Node(f'hostile_sender_{os.getpid()}', context=context)
        publisher = sender.create_publisher(DiagnosticArray, '/diagnostics', 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(watcher)
        spinner = Spinner(executor, 'hostile-executor')
        try:
            wait_for(lambda: publisher.get_subscription_count() > 0, timeout=10.0,
                     what='the watcher subscribed')
            bad = DiagnosticArray(status=[status(prefix, 'no/../topic name', 'x'),
                                          status(prefix, '9ams', 'x')])
            good = DiagnosticArray(status=[status(prefix, 'ams', f'OK{CLEAR}; done',
                                                  state=f'DRIVE{CLEAR}')])

            def live() -> bool:
                publisher.publish(bad)
                publisher.publish(good)
                return 'ams' in watcher.rows
            wait_for(live, timeout=10.0, what='a good status after hostile ones')
            assert spinner.thread.is_alive(), 'the executor thread ended'
            assert watcher.rows == ['ams']
            text = render(watcher.view(1.0), colour=False)
        finally:
            spinner.stop(timeout=3.0)
            watcher.destroy_node()
            sender.destroy_node()
    assert '\x1b' not in text, repr(text)
    assert 'DRIVE\\x1b[2J' in text and 'OK\\x1b[2J\\x1b[31m; done' in text, text
    assert re.search(r"\d+ /diagnostics status\(es\) skipped, the last '(9ams|no/\.\./topic "
                     r"name)': no ROS name", text), text


def test_control_characters_are_escaped_in_every_text_of_the_view():
    view = View(title=f'monitor{CLEAR}', bus='can0\r', bus_state='up\x07',
                rows=[DeviceRow('a\x1bb', 'x', state='S\x1b', message='m\x1b[0m')],
                last_command='c\x1b', notes=['n\x1b', '\u202eevil'])
    text = render(view, colour=False)
    assert not re.search(r'[\x00-\x09\x0b-\x1f\x7f\u202e]', text), repr(text)
    assert printable('3.7 \u00b0C \u2014 ok') == '3.7 \u00b0C \u2014 ok'  # not ASCII-only


def test_a_long_state_widens_its_column_for_every_row():
    """Issue 38, 10: '96 of 96 cell v.' overflowed the STATE column into its row's VOLTAGE."""
    state = state_of({}, '96 of 96 cell voltages missing; check the harness')
    assert state == '96 of 96 cell v.', state
    view = View(rows=[DeviceRow('pack', 'dbc', state=state, level='WARN'),
                      DeviceRow('ams', 'ams', state='PRECHARGING', level='OK')])
    table = render(view, colour=False, unicode=False).splitlines()
    header = next(line for line in table if line.startswith('DEVICE'))
    rows = [line for line in table if line.startswith(('pack ', 'ams '))]
    assert len(rows) == 2
    volt = header.index('VOLTAGE') + len('VOLTAGE')
    assert all(row[:volt].endswith('n/a') for row in rows), rows
