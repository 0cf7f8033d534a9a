# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Print the bridge's parameters as Markdown tables, from the specs the node declares.

Usage: python scripts/param_table.py. The doc build runs it for doc/parameters.md
(doc/docgen.py). test/test_package_readme.py checks that these tables name every parameter the node
declares, for every device type and variant.
"""
from ams_can_bridge import registry
from ams_can_bridge.device_set import variant_spec
from ams_can_bridge.devices.base import device_params
from ams_can_bridge.parameters import allowed_text, BUS_PARAMS, format_number, NODE_PARAMS


COMMON = ('frame_id', 'location', 'serial_number', 'stale_timeout', 'base_id')
CONFIG_NOTES = {'ivt_s': '`write_config` needs every cycle time; `error_masks` unset keeps the '
                         "sensor's",
                ('bms16', 'standard'): '`write_config` needs them all, `balance_v` only with '
                                       '`balance_mode: static`'}


def device_specs(device_type: str, variant: str | None = None) -> list:
    """Return the specs of one device type (and wire form): its own, then its commands'."""
    cls = registry.device_class(device_type, variant)
    return device_params(cls)


def fmt_type(spec) -> str:
    """Return the type as a user writes it in YAML."""
    return spec.type if isinstance(spec.type, str) else spec.type.__name__


def fmt_range(spec) -> str:
    """Return the allowed values, worded as the node's descriptors and errors word them."""
    return allowed_text(spec).replace('|', '\\|')


def fmt_default(spec) -> str:
    """Return the default, or (unset)."""
    if spec.default is None:
        return '(unset)'
    if isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool):
        return format_number(spec.default, spec.key)
    return repr(spec.default).replace("'", '')


def row(name: str, spec) -> str:
    """Return one table row."""
    return (f'| `{name}` | {fmt_type(spec)} | {fmt_default(spec)} | {fmt_range(spec)} '
            f'| {spec.description} |')


def main() -> None:
    """Print the tables: bus and node, every device, each device type."""
    head = '| parameter | type | default | range | description |\n|---|---|---|---|---|'
    print(head)
    for prefix, specs in (('can.', BUS_PARAMS), ('', NODE_PARAMS)):
        for spec in specs:
            print(row(prefix + spec.key, spec))
    print('\nEvery device instance `<name>` (defaults per type below):\n')
    print(head)
    common = {spec.key: spec for spec in device_specs('ams') + device_specs('evms3')}
    print(row('<name>.type', type('S', (), dict(
        key='type', type=str, default=None, choices=registry.DEVICE_TYPES,
        low=None, high=None, step=None, max_length=None,
        description='device type; default: the instance name itself'))))
    for key in COMMON:
        line = row(f'<name>.{key}', common[key])
        if key in ('stale_timeout', 'base_id'):
            line = line.replace(f'| {fmt_default(common[key])} |', '| per type |', 1)
        if key == 'base_id':
            line = line.replace(common[key].description, 'first CAN ID of the device')
            line = line.replace(fmt_range(common[key]), '0x0..0x7FF (29-bit: 0x0..0x1FFFFFFF)')
        print(line)
    print('\nPer type (shown for an instance named after its type):\n')
    print(head)
    for device_type in registry.DEVICE_TYPES:
        for spec in device_specs(device_type):
            if spec.key in COMMON and spec.key not in ('stale_timeout', 'base_id'):
                continue
            if spec.key.startswith('config.'):
                continue
            print(row(f'{device_type}.{spec.key}', spec))
        if device_type in registry.VARIANTS:
            print(row(f'{device_type}.variant', variant_spec(device_type)))
    for device_type in registry.DEVICE_TYPES:
        config = [s for s in device_specs(device_type) if s.key.startswith('config.')]
        if config:
            note = CONFIG_NOTES.get(device_type, '`write_config` needs them all')
            print(f'\n`{device_type}.config.*` (no defaults; {note}):\n')
            print(head)
            for spec in config:
                print(row(f'{device_type}.{spec.key}', spec))
    for device_type, variants in registry.VARIANTS.items():
        default = {spec.key: spec for spec in device_specs(device_type)}
        for variant in list(variants)[1:]:
            specs = [spec for spec in device_specs(device_type, variant)
                     if default.get(spec.key) != spec]
            note = CONFIG_NOTES.get((device_type, variant), '`write_config` needs them all')
            print(f'\nWith `{device_type}.variant: {variant}` these rows replace the '
                  f'{device_type} rows of the same name above, and its `config.*` are these '
                  f'alone (no defaults; {note}):\n')
            print(head)
            for spec in specs:
                print(row(f'{device_type}.{spec.key}', spec))


if __name__ == '__main__':
    main()
