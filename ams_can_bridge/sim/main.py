# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The ``simulator`` executable: simulated battery devices on any python-can bus."""
from __future__ import annotations

import argparse
import inspect
import logging
import signal
import sys
import textwrap
import threading
import time
from typing import Any, Sequence

from ams_can_bridge import registry
from ams_can_bridge.can_io import parse_options
from ams_can_bridge.protocols.dbc_profiles import PROFILES
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.sma import SMA_CONDITIONS
from ams_can_bridge.sim.base import SimDevice
from ams_can_bridge.sim.pair import build_pair, PairScenario, parse_scenario, SCENARIOS
from ams_can_bridge.sim.runner import open_bus, SimRunner

DEFAULT_VIRTUAL_CHANNEL = 'ams_can_bridge'
SUMMARY_AFTER = 0.2  # s of sending before the start line lists each device's IDs
# The descriptors' order (the AMS goes first so the IVT-S can measure its pack); dbc, a
# team's own BMS (--dbc/--mapping), is simulated but not in the default set.
_SORT = tuple(registry.SIMULATORS)
_ORDER = tuple(name for name in _SORT if registry.DESCRIPTORS[name].simulated_by_default)


def _device_list(text: str) -> list[str]:
    types = [t.strip() for t in text.split(',') if t.strip()]
    unknown = [t for t in types if t not in registry.SIMULATORS]
    if unknown or not types:
        raise argparse.ArgumentTypeError(
            f'unknown device type(s) {", ".join(unknown) or "(none)"}: use a comma list of '
            + ', '.join(registry.SIMULATORS))
    return sorted(set(types), key=_SORT.index)


def _fault(text: str) -> tuple[str, str, Any]:
    device, sep, rest = text.partition(':')
    kind, _, value = rest.partition('=')
    if not sep or not device or not kind:
        raise argparse.ArgumentTypeError(
            f'fault {text!r}: write device:kind[=value], e.g. bms16:silent, evms3:error=12, '
            'ams:malformed, ams:drift=0.3, ams:drift_cell=5')
    parsed = parse_options([f'v={value}'])['v'] if value else True
    return device, kind, parsed


def _scenario(text: str) -> tuple[str, float]:
    try:
        return parse_scenario(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


class _EpilogAsWritten(argparse.HelpFormatter):
    """Wrap the description and options as usual; keep the fault table's lines."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith('faults'):
            return text
        return super()._fill_text(text, width, indent)


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface of ``simulator``."""
    p = argparse.ArgumentParser(
        prog='simulator',
        description='Simulated AMS, IVT-S, EVMS3 (+BMS12), BMS16, SMA BMS and a dbc '
                    "device's BMS on a CAN bus, for testing the bridge without hardware. "
                    'Stop with Ctrl-C.',
        epilog=faults_help(), formatter_class=_EpilogAsWritten)
    p.add_argument('--interface', default='virtual',
                   help='python-can interface (virtual, socketcan, slcan, pcan, ...); '
                        'default virtual (in-process only: use the demo for that)')
    p.add_argument('--channel', default=None,
                   help=f'channel (default {DEFAULT_VIRTUAL_CHANNEL!r} for virtual, can0 '
                        'otherwise; a serial device for slcan)')
    p.add_argument('--bitrate', type=int, default=0, help='bit/s, 0 = leave the adapter as is')
    p.add_argument('--option', action='append', default=[], metavar='KEY=VALUE',
                   help='python-can interface option, repeatable (e.g. sleep_after_open=0)')
    p.add_argument('--devices', type=_device_list, default=None,
                   help='comma list of ' + ', '.join(registry.SIMULATORS) + ' (default: '
                   + ', '.join(_ORDER) + '; none of them with --dbc)')
    p.add_argument('--dbc', default=None, metavar='FILE',
                   help="simulate a dbc device's BMS from its DBC (with --mapping; "
                        'doc/own_bms.md; default for --devices dbc: our AMS example)')
    p.add_argument('--mapping', default=None, metavar='FILE',
                   help="the dbc device's mapping file (with --dbc, or to replace a "
                        "--profile's mapping)")
    p.add_argument('--profile', default=None, choices=PROFILES,
                   help='simulate a shipped dbc profile (its DBC and mapping)')
    # defaults as config/ams_ivt.yaml and config/evms3.yaml: the examples run as they are
    p.add_argument('--ams-banks', type=int, default=5, metavar='N',
                   help='AMS banks 1..5 (default 5, as config/ams_ivt.yaml)')
    p.add_argument('--ams-pad', action='store_true',
                   help='the AMS pads every frame to 8 bytes (DLC 8), as some firmwares do')
    p.add_argument('--bms12-modules', type=int, default=4, metavar='N',
                   help='BMS12 modules behind the EVMS3, 0..16 (default 4, as '
                        'config/evms3.yaml)')
    p.add_argument('--evms3-charge-after', type=float, default=None, metavar='S',
                   help='the EVMS3 starts charging after S seconds: it commands its TC '
                        'chargers (29-bit) and they answer (default: never, it drives)')
    p.add_argument('--evms3-state', choices=('running', 'idle', 'charging'), default=None,
                   help="the EVMS3's state at start (default running: key on, driving); "
                        'idle: parked, where write_config is accepted and '
                        'evms3/set_setup_mode true puts it into SETUP')
    p.add_argument('--evms3-chargers', type=int, default=None, metavar='N',
                   help='TC chargers on the EVMS3 bus, 0..3 (default 1)')
    p.add_argument('--ivt-byte-order', choices=('big', 'little'), default=None,
                   help='IVT-S result byte order (default big)')
    p.add_argument('--sma-dialect', choices=('sma', 'pylontech', 'victron'), default=None,
                   help='frames the SMA BMS sends beyond 0x351..0x35F: sma (0x35A alarms), '
                        'pylontech (0x359 alarms and 0x35C instead of 0x35A) or victron '
                        '(0x35A plus 0x370..0x377); default sma')
    p.add_argument('--bms16-variant', choices=tuple(registry.VARIANTS['bms16']), default=None,
                   help='BMS16 wire form: inverter (11-bit, 500 kbit/s, IDs 500.. and SMA; '
                        'default) or standard (EVMS3 protocol, 29-bit: IDs 30.., 301.., 40)')
    p.add_argument('--sma-soc-frame', choices=('sma', 'byd', 'diybms'), default=None,
                   help='0x355 as the SMA BMS sends it: sma (with the high-resolution SoC), '
                        'byd (zeros after the SoH) or diybms (SoC only, DLC 2); default sma')
    p.add_argument('--sma-voltage-scale', type=float, choices=(0.01, 0.1), default=None,
                   help="V per bit of the SMA BMS's 0x356 voltage: 0.01 (SMA, default) or 0.1 "
                        '(as a Discover Lynx II or an Orion BMS 2 sends it)')
    p.add_argument('--sma-no-capacity', action='store_true',
                   help='the SMA BMS sends capacity 0 (not sent) in 0x35F, as Revov/BYD and '
                        'Eco-Worthy batteries do')
    p.add_argument('--pack', action='store_true',
                   help="the two batteries of config/pack.yaml's pack: a standard BMS16 "
                        '(29-bit, base 30) beside an EVMS3 with 11-bit IDs (base 100), '
                        'in parallel at 250 kbit/s (replaces --devices)')
    p.add_argument('--scenario', type=_scenario, action='append', default=[],
                   metavar='NAME[@START]',
                   help='with --pack, repeatable: ' + ', '.join(SCENARIOS) + ' from START s '
                        '(default 2): drift (the EVMS3 falls about 2 V below the BMS16), '
                        'silence (the EVMS3 silent for 4 s), cell_over (an EVMS3 cell 0.3 V '
                        'high for 3 s: past the pack\'s MSL); doc/packs.md')
    p.add_argument('--fault', type=_fault, action='append', default=[],
                   metavar='DEVICE:KIND[=VALUE]',
                   help='inject a fault (repeatable): silent, malformed, error=CODE, '
                        "drift=VOLTS, drift_cell=INDEX, or a model's own (listed below)")
    p.add_argument('--duration', type=float, default=None, metavar='S',
                   help='stop after S seconds (default: run until Ctrl-C)')
    p.add_argument('--tick', type=float, default=0.002, metavar='S', help='model tick period')
    p.add_argument('--status-period', type=float, default=5.0, metavar='S',
                   help='seconds between status lines on stderr')
    p.add_argument('--quiet', action='store_true', help='no startup/status lines')
    p.add_argument('--verbose', action='store_true', help='debug logging')
    return p


def build_devices(types: Sequence[str], ams_banks: int | None = None,
                  bms12_modules: int | None = None,
                  ivt_byte_order: str | None = None,
                  sma_dialect: str | None = None, evms3_charge_after: float | None = None,
                  evms3_chargers: int | None = None, evms3_state: str | None = None,
                  bms16_variant: str | None = None,
                  sma_soc_frame: str | None = None,
                  ams_pad: bool = False, dbc_file: str | None = None,
                  mapping_file: str | None = None, sma_voltage_scale: float | None = None,
                  sma_no_capacity: bool = False,
                  profile: str | None = None) -> list[SimDevice]:
    """Instantiate the simulators named by type (instance name = type name)."""
    devices: list[SimDevice] = []
    ams = None
    for kind in sorted(types, key=_SORT.index):
        cls = registry.simulator_class(kind, bms16_variant if kind == 'bms16' else None)
        kwargs: dict[str, Any] = {'name': kind}
        if kind == 'dbc' and (dbc_file or profile):
            kwargs.update(dbc_file=dbc_file, mapping_file=mapping_file, profile=profile)
        elif kind == 'ams':
            if ams_banks is not None:
                kwargs['bank_count'] = ams_banks
            if ams_pad:
                kwargs['pad'] = True
        elif kind == 'evms3':
            for key, value in (('bms12_modules', bms12_modules), ('chargers', evms3_chargers),
                               ('charge_after_s', evms3_charge_after)):
                if value is not None:
                    kwargs[key] = value
            if evms3_state is not None:
                kwargs['state'] = evms3_state  # the simulator takes the state's name
        elif kind == 'sma':
            for key, text in (('dialect', sma_dialect), ('soc_layout', sma_soc_frame),
                              ('voltage_scale', sma_voltage_scale)):
                if text is not None:
                    kwargs[key] = text
            if sma_no_capacity:
                kwargs['send_capacity'] = False
        elif kind == 'bms16' and 'sma' in types and _accepts(cls, 'send_sma'):
            # The BMS16 also speaks SMA (0x351...): two sources of one ID would clash.
            kwargs['send_sma'] = False
        elif kind == 'ivt_s':
            if ivt_byte_order is not None:
                kwargs['byte_order'] = ivt_byte_order
            if ams is not None:
                # The shunt sits in the AMS pack: both must tell the same story.
                kwargs['current_fn'] = ams.pack_current_a
                kwargs['voltage_fn'] = ams.pack_voltage_v
        device = cls(**kwargs)
        if kind == 'ams':
            ams = device
        devices.append(device)
    return devices


def _accepts(cls: type, name: str) -> bool:
    try:
        return name in inspect.signature(cls).parameters
    except (TypeError, ValueError):
        return False


_FAULT_FIELDS = {'silent': 'silent', 'malformed': 'malformed', 'error': 'error_code',
                 'error_code': 'error_code', 'drift': 'cell_drift_v',
                 'cell_drift_v': 'cell_drift_v', 'drift_cell': 'drift_cell'}

# The model-specific faults each simulator reads from faults.extra (see its docstring), with
# what they do for --help; a simulator class may name its own in EXTRA_FAULTS.
_EXTRA_FAULTS: dict[str, dict[str, str]] = {
    'ams': {'stuck_counter': 'the status counter stops', 'imd_error': 'the IMD error bit'},
    'ivt_s': {'ocs': 'the over-current (OCS) bit',
              'result_error': 'the result error bit on every result',
              'measurement_error': 'the measurement error bit on every result',
              'stuck_counter': 'the result counters stop',
              'mute_commands': 'commands on 0x411 taken but never answered'},
    'evms3': {'config_answer=ID': 'answers ID 51 with only this one of 52..56',
              'charger_status=BITS': 'TC charger status bits (a charger with one set '
                                     'delivers nothing)'},
    'sma': {'alarm=CONDITION': 'this SMA condition alarm ACTIVE',
            'warning=CONDITION': 'this SMA condition warning ACTIVE'},
}


def extra_faults(device_type: str, cls: type | None = None) -> tuple[str, ...]:
    """Return the model-specific fault kinds of a simulator (its class may name its own)."""
    default = tuple(kind.partition('=')[0] for kind in _EXTRA_FAULTS.get(device_type, ()))
    return tuple(getattr(cls, 'EXTRA_FAULTS', default))


def faults_help() -> str:
    """Return the --help epilog listing every fault, the model-specific ones per device."""
    rows = []
    for kind in registry.SIMULATORS:
        described = _EXTRA_FAULTS.get(kind, {})
        for name in extra_faults(kind, registry.simulator_class(kind)):
            spelled = next((k for k in described if k.partition('=')[0] == name), name)
            rows.append((f'{kind}:{spelled}', described.get(spelled, '')))
    width = max(len(fault) for fault, _ in rows)
    return '\n'.join(
        ['faults (--fault DEVICE:KIND[=VALUE], repeatable):',
         '  any device: silent, malformed (wrong DLC), error=CODE (a vendor error code),',
         '    drift=VOLTS (added to one cell), drift_cell=INDEX (which cell, default 0)',
         "  a model's own:"]
        + [f'    {fault.ljust(width)}  {what}'.rstrip() for fault, what in rows]
        + textwrap.wrap('CONDITION: ' + ', '.join(SMA_CONDITIONS), 88,
                        initial_indent='    ', subsequent_indent='      '))


def apply_faults(devices: Sequence[SimDevice], faults: Sequence[tuple[str, str, Any]]) -> None:
    """Set fault switches; raise ConfigError naming an unknown device or fault."""
    by_name = {d.name: d for d in devices}
    for name, kind, value in faults:
        if name not in by_name:
            raise ConfigError(f'--fault {name}:{kind}: no simulated device {name!r} '
                              f'(running: {", ".join(by_name)})')
        target = _FAULT_FIELDS.get(kind)
        device = by_name[name]
        extra = extra_faults(device.TYPE, type(device))
        if target is None and kind not in extra:
            raise ConfigError(f'--fault {name}:{kind}: no such fault of {name}; use one of '
                              + ', '.join(sorted(set(_FAULT_FIELDS) | set(extra))))
        if target is None:
            device.faults.extra[kind] = value
        else:
            setattr(device.faults, target, value)


def _ids(runner: SimRunner) -> str:
    parts = []
    for name, ids in runner.ids_by_device.items():
        # Extended IDs in 8 hex digits, as candump shows them.
        text = ','.join(f'0x{i:08X}' if ext else f'0x{i:03X}' for i, ext in sorted(ids)[:12])
        more = f'+{len(ids) - 12}' if len(ids) > 12 else ''
        parts.append(f'{name}[{text or "-"}{more}]')
    return ' '.join(parts)


def selected_types(args: argparse.Namespace) -> list[str]:
    """Return the device types to simulate: --devices, else the built-ins (none with --dbc)."""
    own = args.dbc or args.profile
    types = args.devices if args.devices is not None else [] if own else list(_ORDER)
    if own and 'dbc' not in types:
        types = [*types, 'dbc']
    return types


def main(argv: Sequence[str] | None = None) -> int:
    """Run the simulator until Ctrl-C, SIGTERM or --duration; 2 if the bus cannot open."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format='%(levelname)s %(name)s: %(message)s')
    channel = args.channel or (DEFAULT_VIRTUAL_CHANNEL if args.interface == 'virtual'
                               else 'can0')
    try:
        options = parse_options(args.option)
        if args.profile and args.dbc:
            raise ConfigError(f'--profile {args.profile} brings its own DBC: drop --dbc')
        if not args.profile and bool(args.dbc) != bool(args.mapping):
            raise ConfigError('--dbc and --mapping go together')
        if args.scenario and not args.pack:
            raise ConfigError('--scenario plays on the pair of config/pack.yaml: add --pack')
        if args.pack and (args.devices is not None or args.dbc or args.profile):
            raise ConfigError('--pack brings its own two devices: drop --devices/--dbc/--profile')
        devices = build_pair() if args.pack else build_devices(
            selected_types(args), args.ams_banks, args.bms12_modules, args.ivt_byte_order,
            args.sma_dialect, args.evms3_charge_after, args.evms3_chargers,
            evms3_state=args.evms3_state, bms16_variant=args.bms16_variant,
            sma_soc_frame=args.sma_soc_frame, ams_pad=args.ams_pad, dbc_file=args.dbc,
            mapping_file=args.mapping, sma_voltage_scale=args.sma_voltage_scale,
            sma_no_capacity=args.sma_no_capacity, profile=args.profile)
        apply_faults(devices, args.fault)
        if args.scenario:  # first: it steers the pair before they tick
            devices.insert(0, PairScenario(devices, args.scenario))
    except (ValueError, TypeError, ImportError) as exc:
        print(f'simulator: {exc}', file=sys.stderr)
        return 2
    try:
        bus = open_bus(args.interface, channel, args.bitrate, options)
    except KeyboardInterrupt:  # Ctrl-C in python-can's wait after opening a serial port
        print('simulator: stopped before the bus was open', file=sys.stderr)
        return 0
    except Exception as exc:
        print(f'simulator: cannot open CAN bus {args.interface}:{channel}: {exc}',
              file=sys.stderr)
        return 2

    done = threading.Event()
    try:
        # An event rather than KeyboardInterrupt: Ctrl-C cannot land half-way through the
        # shutdown, and it works even when started with SIGINT ignored (background job).
        signal.signal(signal.SIGTERM, lambda *_: done.set())
        signal.signal(signal.SIGINT, lambda *_: done.set())
    except ValueError:  # not the main thread (called from a test): --duration only
        pass
    runner = SimRunner(bus, devices, tick_period=args.tick)
    say = (lambda text: None) if args.quiet else (
        lambda text: print(f'simulator: {text}', file=sys.stderr, flush=True))
    try:
        started = time.monotonic()
        runner.start()
        # The start line lists the IDs sent so far: every model sends each periodic frame
        # once within its first SUMMARY_AFTER (a dbc device's messages follow its primary
        # a millisecond apart), so it lists them all, not only the first tick's.
        done.wait(min(SUMMARY_AFTER, args.duration if args.duration is not None
                      else SUMMARY_AFTER))
        say(f'{len(devices)} device(s) on {args.interface}:{channel}'
            + (f' at {args.bitrate} bit/s' if args.bitrate else '') + ': ' + _ids(runner))
        clashes = runner.shared_ids()
        if clashes:
            say('warning: several devices send the same ID(s) '
                + ', '.join(f'0x{i:X}' for i, _ in clashes) + ': choose --devices')
        end = started + args.duration if args.duration is not None else None
        next_status = started + args.status_period
        while not done.is_set():
            now = time.monotonic()
            if end is not None and now >= end:
                break
            if now >= next_status:
                next_status += args.status_period
                say(f'{now - started:.0f} s: {runner.frames_sent} frames sent, '
                    f'{runner.frames_received} received, {runner.send_errors} send errors')
            wake = min(x for x in (end, next_status) if x is not None)
            done.wait(max(0.0, min(wake - now, 0.5)))
    except KeyboardInterrupt:
        pass
    finally:
        runner.stop()
        try:
            bus.shutdown()
        except Exception:  # an adapter unplugged under us: nothing left to close
            pass
    say(f'stopped: {runner.frames_sent} frames sent, {runner.send_errors} send errors')
    return 0


if __name__ == '__main__':
    sys.exit(main())
