# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Links between devices (the AMS and its IVT-S): declared by the device, resolved by DeviceSet.

The parameter keeps what the user set ('' stays ''); the instance chosen shows in the AMS's
diagnostics and in ``DeviceSet.links``. The AMS reads its IVT-S before taking its own lock
(lock order), proved here with an interleaving that deadlocks otherwise (bounded waits).
"""
import threading

import pytest

from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.base import Device
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.errors import ConfigError
from helpers import Clock

STAMP = 1.7e9
WAIT = 5.0  # s, the bound of every wait here (reached only when the test fails)


def device_set(names, **params):
    return DeviceSet(names, lambda name, spec: params.get(name, spec.default))


def test_the_ams_declares_its_link_and_device_set_knows_no_type_names():
    assert AmsDevice.LINKS == {'current_sensor': 'ivt_s'}
    assert Device.LINKS == {} and IvtSDevice.LINKS == {}
    import inspect
    from ams_can_bridge import device_set as module
    source = inspect.getsource(module)
    assert "'ams'" not in source and "'ivt_s'" not in source


def test_an_unset_current_sensor_stays_unset_and_the_first_ivt_s_is_used():
    devices = device_set(['ams', 'shunt', 'other'],
                         **{'shunt.type': 'ivt_s', 'other.type': 'ivt_s', 'other.base_id': 0x621,
                            'other.command_id': 0x412, 'other.answer_id': 0x512})
    ams = devices.devices['ams']
    assert ams.current_sensor is devices.devices['shunt']
    assert ams.config.current_sensor == ''  # the parameter server's value, unchanged
    values = ams.diagnostic_report().values
    assert values['current sensor'] == 'shunt'
    assert values['current sensor chosen by'] == 'the first ivt_s (ams.current_sensor unset)'
    assert devices.links == {
        'ams.current_sensor': 'shunt (the first ivt_s (ams.current_sensor unset))'}


def test_a_named_current_sensor_is_used_as_named():
    devices = device_set(['ams', 'shunt', 'other'],
                         **{'shunt.type': 'ivt_s', 'other.type': 'ivt_s', 'other.base_id': 0x621,
                            'other.command_id': 0x412, 'other.answer_id': 0x512,
                            'ams.current_sensor': 'other'})
    ams = devices.devices['ams']
    assert ams.current_sensor is devices.devices['other']
    assert ams.config.current_sensor == 'other'
    assert ams.diagnostic_report().values['current sensor chosen by'] == 'ams.current_sensor'


def test_no_ivt_s_no_link_and_a_wrong_name_is_refused():
    alone = device_set(['ams'])
    assert alone.devices['ams'].current_sensor is None and alone.links == {}
    assert 'current sensor chosen by' not in alone.devices['ams'].diagnostic_report().values
    with pytest.raises(ConfigError) as info:
        device_set(['ams', 'bms16'], **{'ams.current_sensor': 'bms16'})
    assert 'ams.current_sensor' in str(info.value) and 'ivt_s' in str(info.value)


class _WatchedLock:
    """The IVT-S lock, telling when another thread starts waiting for it."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.waiting = threading.Event()

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        if threading.current_thread() is not threading.main_thread():
            self.waiting.set()
        return self._lock.acquire(blocking, timeout)

    def release(self) -> None:
        self._lock.release()

    def __enter__(self) -> bool:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


@pytest.mark.parametrize('read', [lambda ams: ams.battery_report(),
                                  lambda ams: ams.snapshot()[0]],
                         ids=['battery_report', 'engine snapshot'])
def test_the_ams_reads_its_ivt_s_before_taking_its_own_lock(read):
    """
    IVT-S lock held (as by an IVT-S calling into the AMS) while the AMS builds its report.

    AMS -> IVT-S nesting would leave the report thread holding the AMS lock while it waits
    for the IVT-S: the AMS lock could not be taken here, the classic two-lock deadlock.
    """
    clock = Clock(50.0)
    ivt = IvtSDevice('shunt', {}, clock=clock)
    ams = AmsDevice('ams', {}, clock=clock)
    ams.attach_current_sensor(ivt)
    ams.handle_frame(0x300, bytes([0xC0, 1 << 5 | 3, 180, 35, 77, 0, 0]), STAMP)
    ivt.handle_frame(0x521, bytes([0, 0]) + (120_500).to_bytes(4, 'big', signed=True), STAMP)
    ivt.lock = watched = _WatchedLock()
    reports = []
    with watched:
        worker = threading.Thread(target=lambda: reports.append(read(ams)),
                                  daemon=True)
        worker.start()
        assert watched.waiting.wait(WAIT), 'battery_report never asked for the IVT-S'
        took_ams_lock = ams.lock.acquire(timeout=WAIT)
        if took_ams_lock:
            ams.lock.release()
    worker.join(WAIT)
    assert took_ams_lock, 'the AMS held its lock while waiting for the IVT-S lock'
    assert not worker.is_alive() and reports[0].current == pytest.approx(-120.5)
