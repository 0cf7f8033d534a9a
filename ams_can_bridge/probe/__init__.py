# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
``probe``: what is on this bus, and how does the bridge read it? (doc/real_bus.md).

Listens (a log, or a live bus opened receive-only) and never sends. ``traffic`` keeps what
every CAN ID showed (count, DLCs, rate, a sample of payloads); one recogniser per device
family (``ams``, ``ivt_s``, ``evms3``, ``bms16``, ``sma``, ``dbc``) turns that into
candidate devices with their evidence, settings and a confidence (``sma_voltage`` then
decides the SMA battery's 0x356 voltage scale); ``recognise`` runs them,
settles two candidates for the same IDs and lists what nobody placed; ``output`` writes the
params file and checks it with the bridge's own start-up checks; ``report`` words it all
(text or JSON); ``sources`` reads a log or a live bus; ``main`` is the command line.

No ROS anywhere: ``probe`` runs on a machine without it.
"""
