# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Real-time scheduling of the bridge's own senders: SCHED_FIFO at the priority the user gives.

A sender's thread (the AMS heartbeat, the charger repeat, the SMA keep-alive) sleeps until
its slot; on a busy computer the kernel may run other programs first when it wakes, and
the frame is late. Under SCHED_FIFO it runs as soon as it wakes, before every ordinary
program. Only the senders get it: their work per slot is a few microseconds, so they cannot
starve the machine. The priority is the node's ``realtime_priority`` (0: the default
scheduling), checked once at configure (``use``); each sender thread takes it when it
starts (``enter``). Linux only; elsewhere, and without the right (root, CAP_SYS_NICE or an
``rtprio`` limit), ``use`` says why and the senders keep the default scheduling.
"""
from __future__ import annotations

import os
import threading

PRIORITY_MAX = 98  # 99 is left to the kernel's own threads (watchdog, migration)
HOW_TO_GRANT = ('give the bridge the right: an rtprio limit for its user (/etc/security/'
                'limits.conf: "<user> - rtprio 98"), CAP_SYS_NICE (setcap cap_sys_nice+ep on '
                'the Python interpreter), or LimitRTPRIO=98 in a systemd unit; or set '
                'realtime_priority: 0 (doc/real_bus.md)')

_priority = 0  # what sender threads take when they start (set by ``use``)


def use(priority: int) -> str:
    """
    Make sender threads started from now on run at ``priority`` (0: default scheduling).

    The right to do so is tried at once, on the calling thread (put back as it was): ''
    when granted, otherwise why not and what to change, and the senders keep the default.
    """
    global _priority
    _priority = 0
    if priority <= 0:
        return ''
    problem = _try(priority)
    if not problem:
        _priority = priority
    return problem


def priority() -> int:
    """Return the SCHED_FIFO priority sender threads take (0: none)."""
    return _priority


def enter() -> None:
    """Give the calling thread, a sender just started, the priority ``use`` granted."""
    if _priority:
        try:
            os.sched_setscheduler(threading.get_native_id(), os.SCHED_FIFO,
                                  os.sched_param(_priority))
        except OSError:
            pass  # granted at configure; a right withdrawn since leaves the default


def _try(priority: int) -> str:
    if not hasattr(os, 'sched_setscheduler'):
        return (f'realtime_priority {priority}: SCHED_FIFO is not available on this system; '
                'the senders run at the default scheduling')
    tid = threading.get_native_id()
    try:
        policy, param = os.sched_getscheduler(tid), os.sched_getparam(tid)
        os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:
        return (f'realtime_priority {priority}: cannot use SCHED_FIFO ({exc.strerror or exc}); '
                f'the senders run at the default scheduling. To use it, {HOW_TO_GRANT}')
    os.sched_setscheduler(tid, policy, param)  # lowering back is always allowed
    return ''
