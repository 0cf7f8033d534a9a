# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Which AMS state a car command needs first: doc/protocols.md section 1.4.

The seed's car path is IDLE -> SC_ENABLED -> TS_ACTIVE -> DRIVE, one command a step, so a
state command the AMS reports it cannot carry out from its present state is answered at once
(``AmsMaster.command``) instead of after ``ams.command_timeout``. Split from
``ams_master.py`` to keep that file about the heartbeat and the waits.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from ams_can_bridge.protocols.ams import AmsState, CarCommand

if TYPE_CHECKING:  # the master imports this module; the view is only a type here
    from ams_can_bridge.devices.ams.master import AmsView

# State command -> (the state it is given in, every state it can still succeed from): the
# state itself, the target already reached, and PRECHARGING on the way to TS_ACTIVE.
PRECONDITIONS = {
    CarCommand.ENABLE_SC: (AmsState.IDLE, (AmsState.IDLE, AmsState.SC_ENABLED)),
    CarCommand.ENABLE_TS: (AmsState.SC_ENABLED, (AmsState.SC_ENABLED, AmsState.PRECHARGING,
                                                 AmsState.TS_ACTIVE)),
    CarCommand.ENABLE_DRIVE: (AmsState.TS_ACTIVE, (AmsState.TS_ACTIVE, AmsState.DRIVE)),
}
# The car path and the service that takes the AMS from each state to the next.
CAR_PATH = (AmsState.IDLE, AmsState.SC_ENABLED, AmsState.TS_ACTIVE)
STEP_SERVICE = {AmsState.IDLE: 'enable_sc', AmsState.SC_ENABLED: 'enable_ts',
                AmsState.TS_ACTIVE: 'enable_drive'}


def precondition_refusal(command: CarCommand, view: AmsView) -> str:
    """Say why command cannot succeed from the AMS state in view ('' = it may)."""
    rule = PRECONDITIONS.get(command)
    if rule is None or view.status_seq == 0 or view.stale or view.state == 0:
        return ''  # not a state command, or the state is unknown: let the AMS answer
    required, possible = rule
    if view.state in possible:
        return ''
    state = AmsState(view.state)
    goal = CAR_PATH.index(required)
    if state is AmsState.PRECHARGING and required is AmsState.TS_ACTIVE:
        hint = 'wait for TS_ACTIVE, or call abort'
    else:
        if state in CAR_PATH and CAR_PATH.index(state) < goal:
            steps = [STEP_SERVICE[s] for s in CAR_PATH[CAR_PATH.index(state):goal]]
        else:  # past the required state, in an error or a charging state: back to IDLE
            steps = ['abort'] + [STEP_SERVICE[s] for s in CAR_PATH[:goal]]
        hint = 'call ' + ', then '.join(steps)
    return (f'{command.name} refused: the AMS is in {state.name}, and {command.name} can '
            f'only succeed from {required.name}: it must be {required.name} first '
            f'({hint}); nothing was sent, the heartbeat carries NO_COMMAND; '
            f'{view.describe()}')
