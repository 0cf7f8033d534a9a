# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A disarm during an EVMS3 write_config (issue 26, point 11).

Decision: the disarm wins at once (the gate lets no frame out after commands_enabled went
false, even of a sequence under way), and the call answers exactly which frames went out,
which did not, and what that leaves in the EVMS3: frames 36 and 32..34 change its RAM only;
its EEPROM is written when 35 arrives (doc/protocols.md 3.6), so a cut-short write is gone
at the next power-up. The pause after each frame is stretched here so the disarm lands
between two frames every time (ZEVA's Monitor: 20 ms).
"""
from __future__ import annotations

from std_srvs.srv import Trigger

from shared import EVMS3_FRAMES, evms3_in, evms3_params, IDLE, sent

GAP = 0.5  # s after each frame, instead of the Monitor's 20 ms: room for the disarm


def test_a_disarm_during_write_config_stops_it_and_the_answer_says_what_was_sent(
        rig_factory, capfd):
    rig = rig_factory(evms3_params())
    evms3_in(rig, IDLE)
    rig.node.devices['evms3'].CONFIG_FRAME_GAP = GAP
    mark = rig.capture.mark()
    call = rig.call_in_thread(Trigger, '/evms3/write_config')
    rig.wait(lambda: sent(rig, mark), what='the first configuration frame')
    assert rig.set_param('commands_enabled', False).successful
    frames_out = rig.frames_out()
    call['thread'].join(10.0)
    answer = call['response']
    assert not answer.success
    first_id, first_data = EVMS3_FRAMES[0]
    assert sent(rig, mark) == [(first_id, first_data, True)], 'frames after the disarm'
    message = answer.message
    assert ('evms3: write the configuration failed at ID 32 (0x20)' in message
            and 'commands are disabled' in message), message
    assert f'sent before it: ID 36 (0x24) [{first_data.hex(" ").upper()}]' in message
    assert 'not sent: ID 32, ID 33, ID 34, ID 35' in message
    assert ('saves its configuration to EEPROM only when ID 35 arrives, so the frames sent '
            'changed its RAM only') in message
    assert 'call write_config again (all five frames) once commands are enabled' in message
    rig.assert_silent_since(frames_out)
    err = capfd.readouterr().err
    assert any(line.startswith('[WARN]') and 'evms3/write_config: answered success=False'
               in line for line in err.splitlines()), err[-2000:]
