# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Two linked serial ports without socat: ``python bench/pty_link.py A B``.

Creates two pseudo-terminals in raw mode, links their device paths to A and B and copies
every byte written to one to the other until killed, as ``socat pty,raw,echo=0,link=A
pty,raw,echo=0,link=B`` does. The benchmarks use socat where it is installed; this keeps
``./dev bench`` working on a machine with nothing but Python.
"""
import os
import select
import signal
import sys
import tty


def main() -> None:
    """Link the two ports and relay until SIGTERM/SIGINT."""
    a, b = sys.argv[1], sys.argv[2]
    (m1, s1), (m2, s2) = os.openpty(), os.openpty()
    for slave in (s1, s2):
        # Raw, no echo. The slave ends stay open here too, so a reader's close never
        # makes the master read EIO while nobody has the port open.
        tty.setraw(slave)
    os.symlink(os.ttyname(s1), a)
    os.symlink(os.ttyname(s2), b)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    other = {m1: m2, m2: m1}
    try:
        while True:
            ready, _, _ = select.select([m1, m2], [], [])
            for master in ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # the port is being reopened
                    continue
                os.write(other[master], data)
    except KeyboardInterrupt:
        pass
    finally:
        for link in (a, b):
            try:
                os.unlink(link)
            except FileNotFoundError:
                pass


if __name__ == '__main__':
    main()
