# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe --bitrate auto on slcan: only the rates the interface has, every one of them, and honesty.

The adapter is ``SlcanPeer`` on a pty. A silent bus is "no traffic at any rate" after every
rate python-can's slcan can set (800 kbit/s is not one of them); a rate the adapter does not
take is skipped, not the end of the search; a link that delivers frames at every rate (a pty
or a software link has no bit rate) is reported as "rate not determined", never as the first
rate tried, and the params file leaves the rate to check.
"""
from __future__ import annotations

import io
import threading

import pytest

from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.probe import sources
from ams_can_bridge.probe.main import main
from ams_can_bridge.protocols.common import Frame
from slcan_peer import SlcanPeer

OPTIONS = {'sleep_after_open': 0}
SLCAN_CODES = {10_000: 'S0', 20_000: 'S1', 50_000: 'S2', 100_000: 'S3', 125_000: 'S4',
               250_000: 'S5', 500_000: 'S6', 1_000_000: 'S8'}  # python-can's slcan table


@pytest.fixture(autouse=True)
def short_windows(monkeypatch):
    monkeypatch.setattr(sources, 'AUTO_WINDOW_S', 0.3)


class EveryRate:
    """Frames to the adapter whenever it is open, whatever rate was set: a link with no rate."""

    def __init__(self, peer: SlcanPeer) -> None:
        self.peer = peer
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.wait(0.01):
            if self.peer.is_open:
                self.peer.send(Frame(0x123, b'\x01\x02', False))

    def __enter__(self) -> 'EveryRate':
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(2.0)


def test_auto_tries_only_the_rates_slcan_has_and_says_no_traffic(tmp_path):
    assert 800_000 not in sources.AUTO_RATES
    with SlcanPeer(symlink=tmp_path / 'ttyACM_silent') as peer:
        with pytest.raises(LogFileError) as exc:
            sources.listen_live('slcan', peer.channel, 'auto', 0.3, OPTIONS, io.StringIO())
        tried = [c for c in peer.commands if c[:1] == 'S']
    assert 'no traffic at any rate' in str(exc.value)
    assert tried == [SLCAN_CODES[r] for r in sources.AUTO_RATES]
    assert set(tried) == set(SLCAN_CODES.values())  # every rate slcan can set, once each
    assert '800000' not in str(exc.value)


def test_a_rate_the_adapter_does_not_take_is_skipped(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, 'AUTO_RATES', (800_000, 500_000, 250_000))
    stream = io.StringIO()
    with SlcanPeer(symlink=tmp_path / 'ttyACM_refuse') as peer:
        with pytest.raises(LogFileError) as exc:
            sources.listen_live('slcan', peer.channel, 'auto', 0.3, OPTIONS, stream)
        tried = [c for c in peer.commands if c[:1] == 'S']
    assert tried == ['S6', 'S5']  # the search went on after 800k
    assert 'refused by the adapter: 800000' in str(exc.value)
    assert '800000 bit/s: not taken by the adapter, skipped' in stream.getvalue()


def test_no_rate_at_all_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(sources, 'AUTO_RATES', (800_000, 900_000))
    with SlcanPeer(symlink=tmp_path / 'ttyACM_none') as peer:
        with pytest.raises(ConfigError) as exc:
            sources.listen_live('slcan', peer.channel, 'auto', 0.3, OPTIONS, io.StringIO())
    assert 'opened at no rate' in str(exc.value)


def test_a_link_without_a_bit_rate_is_not_reported_as_the_first_rate(tmp_path, capsys):
    out = tmp_path / 'probe.yaml'
    with SlcanPeer(symlink=tmp_path / 'ttyACM_pty') as peer, EveryRate(peer):
        code = main(['--interface', 'slcan', '--channel', peer.channel, '--bitrate', 'auto',
                     '--duration', '0.5', '--option', 'sleep_after_open=0',
                     '--output', str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert 'rate not determined' in captured.err
    assert 'rate not determined' in captured.out
    assert 'rate found by trying' not in captured.out
    params = load_parameters(str(out), NODE_NAME)
    assert 'can.bitrate' not in params  # left to check, commented out
    assert params['can.interface'] == 'slcan' and params['can.channel'] == peer.channel
    text = out.read_text()
    assert '      # bitrate: 500000\n' in text
    assert 'no bit rate of its own' in ' '.join(text.replace('#', ' ').split())
