# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Device types are plugins: the entry-point group ams_can_bridge.devices, built-in ones included.

``registry.discover`` loads the descriptors of the entry points; these tests hand it entry
points of modules written to a temporary directory (a plugin, broken ones, clashing ones), so
no package is installed. The installed metadata of this package is checked to register every
built-in type, and a node with only a BMS16 to import no other device's code.
"""
from __future__ import annotations

from importlib.metadata import entry_points, EntryPoint
import subprocess
import sys
import textwrap

import pytest

from ams_can_bridge import registry
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.builtin import BUILT_IN
from ams_can_bridge.devices.descriptor import DeviceType, ENTRY_POINT_GROUP
from ams_can_bridge.errors import ConfigError

PLUGIN = '''
from ams_can_bridge.devices.descriptor import DeviceType
REC = DeviceType(name='rec', device='rec_device:RecDevice', simulator='rec_sim:RecSimulator')
OTHER = DeviceType(name='rec', device='elsewhere:RecDevice')
WRONG_NAME = DeviceType(name='zeva_x', device='rec_device:RecDevice')
AMS_AGAIN = DeviceType(name='ams', device='rec_device:RecDevice')
NOT_A_TYPE = 'rec_device:RecDevice'
'''


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """Make a module 'fake_plugin' (descriptors) and 'broken_plugin' (raises) importable."""
    (tmp_path / 'fake_plugin.py').write_text(PLUGIN)
    (tmp_path / 'broken_plugin.py').write_text("raise RuntimeError('vendor SDK missing')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ('fake_plugin', 'broken_plugin'):
        monkeypatch.delitem(sys.modules, name, raising=False)


def point(name, value):
    return EntryPoint(name, value, ENTRY_POINT_GROUP)


def test_this_package_registers_every_built_in_type_as_an_entry_point():
    found = {p.name: p for p in entry_points(group=ENTRY_POINT_GROUP)}
    assert {d.name for d in BUILT_IN} <= set(found)
    for descriptor in BUILT_IN:
        assert found[descriptor.name].load() is descriptor
    assert registry.DEVICE_TYPES[:len(BUILT_IN)] == tuple(d.name for d in BUILT_IN)
    assert registry.BROKEN == {}


def test_a_plugin_is_a_device_type_after_the_built_in_ones(plugins):
    types, broken = registry.discover([point('rec', 'fake_plugin:REC'),
                                       point('ams', 'ams_can_bridge.devices.builtin:AMS')])
    assert broken == {}
    assert list(types) == [d.name for d in BUILT_IN] + ['rec']
    assert types['rec'].simulator == 'rec_sim:RecSimulator'


def test_a_plugin_that_fails_to_load_is_left_out_and_said_why(plugins, caplog):
    types, broken = registry.discover([point('vendor', 'broken_plugin:TYPE'),
                                       point('rec', 'fake_plugin:REC')])
    assert list(types) == [d.name for d in BUILT_IN] + ['rec']  # the others still load
    assert broken == {'vendor': 'entry point vendor = broken_plugin:TYPE failed to load: '
                                'RuntimeError: vendor SDK missing'}
    assert "device type 'vendor' not available" in caplog.text


@pytest.mark.parametrize('points, why', [
    ([('rec', 'fake_plugin:NOT_A_TYPE')], 'is a str, not an ams_can_bridge.devices.descriptor'),
    ([('rec', 'fake_plugin:WRONG_NAME')], "names its DeviceType 'zeva_x': the entry point and "
                                          'the descriptor must have the same name'),
    ([('ams', 'fake_plugin:AMS_AGAIN')], "'ams' is a built-in device type; give the plugin a "
                                         'name of its own'),
    ([('rec', 'fake_plugin:REC'), ('rec', 'fake_plugin:OTHER')],
     'another installed package has that name too'),
])
def test_a_plugin_that_cannot_be_used_is_named_with_the_reason(plugins, points, why):
    types, broken = registry.discover([point(*p) for p in points])
    name = points[-1][0]
    assert why in broken[name]
    assert name not in types or types[name] is registry.DESCRIPTORS['ams']  # built-in stays


def test_an_unknown_type_names_the_installed_ones_and_a_broken_one_its_failure(monkeypatch):
    with pytest.raises(ConfigError, match="unknown device type 'rec': use one of ams, ivt_s, "
                                          'evms3, bms16, sma, dbc, pack .the installed'):
        registry.device_class('rec')
    monkeypatch.setitem(registry.BROKEN, 'rec', 'entry point rec = x:Y failed to load: boom')
    with pytest.raises(ConfigError, match="device type 'rec' is installed but unusable: entry "
                                          'point rec = x:Y failed to load: boom'):
        registry.device_class('rec')
    # the bridge's start: the instance names the plugin's failure, not only "unknown"
    with pytest.raises(ConfigError, match="rec.type: device type 'rec' is installed but "
                                          'unusable'):
        DeviceSet(['rec'], lambda name, spec: spec.default)


def test_a_descriptor_holds_the_rows_of_its_type():
    bms16 = registry.descriptor('bms16')
    assert isinstance(bms16, DeviceType) and bms16.variant_names == ('inverter', 'standard')
    assert [r.service for r in bms16.commands('standard')] == [
        r.service for r in registry.device_class('bms16', 'standard').COMMANDS]
    assert 'base_id' in {spec.key for spec in bms16.params()}
    with pytest.raises(ConfigError, match="bms16 has no variant 'v3': use one of inverter, "
                                          'standard'):
        bms16.device_class('v3')


def test_a_node_with_only_a_bms16_imports_no_other_devices_code():
    code = textwrap.dedent('''
        import sys
        from ams_can_bridge.device_set import DeviceSet
        DeviceSet(['bms16'], lambda name, spec: spec.default)
        print(sorted(m for m in sys.modules if m.startswith('ams_can_bridge.devices.')))
    ''')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    loaded = eval(out)  # noqa: S307 (a list printed by the child)
    assert 'ams_can_bridge.devices.bms16.inverter' in loaded
    # (the BMS16 also speaks SMA: devices.sma.device is its own code too)
    for other in ('ams', 'ivt_s', 'evms3', 'dbc', 'bms16.standard', 'pack.device'):
        assert f'ams_can_bridge.devices.{other}' not in loaded, loaded
