#!/usr/bin/env bash
# Both ways of installing the package, checked as a user would meet them:
#  1. colcon build in a scratch ROS workspace: files where ROS expects them, then the
#     installed code finds its msg_defs/ with the workspace sourced, run from elsewhere;
#  2. pip install . into a fresh virtual environment with the pinned ROS wheels.
# Usage: scripts/check_install.sh [python-of-the-dev-venv]  (./dev setup makes .venv first)
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
py=${1:-$here/.venv/bin/python}
bin=$(dirname "$py")
scratch=$(mktemp -d)
trap '[ -n "${KEEP_SCRATCH:-}" ] || rm -rf "$scratch"' EXIT
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$(( ($$ % 100) + 100 ))}
fail() { echo "check_install: FAIL: $*" >&2; exit 1; }

probe='
import sys
from pathlib import Path
from ams_can_bridge.protocols.common import load_dbc, msg_defs_dir
d = msg_defs_dir()
assert Path(sys.argv[1]) in d.parents, f"msg_defs found at {d}, not under {sys.argv[1]}"
names = sorted(p.stem for p in d.glob("*.dbc"))
assert names == ["ams", "bms16", "evms3", "ivt_s", "sma"], names
for n in names:
    assert load_dbc(n).messages
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.dbc_profiles import PROFILES, profile_files
for p in PROFILES:  # the dbc profiles: installed beside msg_defs, found, loading
    dbc, mapping = profile_files(p)
    assert Path(sys.argv[1]) in dbc.parents, f"profile {p} found at {dbc}"
    assert (dbc.parent / "README.md").is_file() and mapping.is_file()
    assert DbcDevice("pack", {"profile": p}).plan.messages, p
# the device types: registered as entry points by the installed metadata, all loading
from importlib.metadata import distributions
from ams_can_bridge import registry
from ams_can_bridge.devices.builtin import BUILT_IN
[dist] = [x for x in distributions(path=[str(p) for p in Path(sys.argv[1]).rglob("site-packages")])
          if x.metadata["Name"] == "ams_can_bridge"]
points = dist.entry_points.select(group="ams_can_bridge.devices")
assert sorted(e.name for e in points) == sorted(b.name for b in BUILT_IN), points
assert all(e.load() in BUILT_IN for e in points) and registry.BROKEN == {}, registry.BROKEN
print("msg_defs at", d, "; profiles", ", ".join(PROFILES), "; device types",
      ", ".join(registry.DEVICE_TYPES))
'

echo "== colcon build in $scratch/ws"
pkg="$scratch/ws/src/ams_can_bridge"
mkdir -p "$pkg"
# The package as git sees it: tracked files plus new ones not ignored (no .venv, no build/).
(cd "$here" && git ls-files -z --cached --others --exclude-standard \
   | xargs -0 -I{} sh -c '[ -e "{}" ] && printf "%s\0" "{}"' \
   | tar --null -T - -cf -) | tar -C "$pkg" -xf -
[ -f "$pkg/package.xml" ] || fail "copying the source tree"
(cd "$scratch/ws" && PATH="$bin:$PATH" "$bin/colcon" build --event-handlers console_direct- \
   > "$scratch/colcon.log" 2>&1) || { tail -40 "$scratch/colcon.log"; fail "colcon build"; }
inst="$scratch/ws/install/ams_can_bridge"
for f in lib/ams_can_bridge/bridge lib/ams_can_bridge/ams-can-bridge \
         lib/ams_can_bridge/simulator lib/ams_can_bridge/demo \
         lib/ams_can_bridge/log2bag lib/ams_can_bridge/monitor lib/ams_can_bridge/probe \
         lib/ams_can_bridge/bridgectl \
         share/ams_can_bridge/config/foxglove_layout.json \
         share/ams_can_bridge/package.xml share/ams_can_bridge/launch/bridge.launch.py \
         share/ams_can_bridge/security/policy.xml \
         share/ament_index/resource_index/packages/ams_can_bridge; do
  [ -e "$inst/$f" ] || fail "colcon install lacks $f"
done
for f in ams ivt_s evms3 bms16 sma; do
  [ -f "$inst/share/ams_can_bridge/msg_defs/$f.dbc" ] || fail "colcon install lacks msg_defs/$f.dbc"
done
ls "$inst"/share/ams_can_bridge/config/*.yaml >/dev/null || fail "colcon install lacks config/*.yaml"
for f in foxbms2/foxbms.dbc foxbms2/mapping.yaml foxbms2/BSD-3-Clause.txt \
         orion_bms2/orion_bms2.dbc orion_bms2/mapping.yaml; do
  [ -f "$inst/share/ams_can_bridge/config/profiles/$f" ] \
    || fail "colcon install lacks config/profiles/$f"
done
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  "$py" -c "$probe" "$inst") || fail "colcon-installed package does not find its msg_defs"
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  PATH="$bin:$PATH" timeout 60 ws/install/ams_can_bridge/lib/ams_can_bridge/simulator --help \
  >/dev/null) || fail "installed simulator --help"
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  PATH="$bin:$PATH" timeout 60 ws/install/ams_can_bridge/lib/ams_can_bridge/monitor --help \
  >/dev/null) || fail "installed monitor --help"
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  PATH="$bin:$PATH" timeout 60 ws/install/ams_can_bridge/lib/ams_can_bridge/probe --help \
  >/dev/null) || fail "installed probe --help"
# the bridge's second name: what a colcon user runs without `ros2 run` (iproute2 owns bridge)
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  PATH="$bin:$PATH" timeout 60 ws/install/ams_can_bridge/lib/ams_can_bridge/ams-can-bridge \
  --help | grep -q 'ams-can-bridge') || fail "installed ams-can-bridge --help"
(cd "$scratch" && set +u && source ws/install/setup.bash && set -u && \
  PATH="$bin:$PATH" timeout 60 ws/install/ams_can_bridge/lib/ams_can_bridge/bridgectl --help \
  >/dev/null) || fail "installed bridgectl --help"
echo "colcon build: OK ($inst)"

echo "== pip install . into a fresh venv"
"$py" -m venv "$scratch/venv"
"$scratch/venv/bin/python" -m pip install --quiet --upgrade pip
"$scratch/venv/bin/python" -m pip install --quiet -r "$here/requirements.txt" "$here" \
  || fail "pip install ."
(cd "$scratch" && "$scratch/venv/bin/python" -c "$probe" "$scratch/venv") \
  || fail "pip-installed package does not find its msg_defs"
for exe in bridge ams-can-bridge simulator demo log2bag monitor probe bridgectl; do
  [ -x "$scratch/venv/bin/$exe" ] || fail "pip install lacks the $exe executable"
done
(cd "$scratch" && timeout 60 "$scratch/venv/bin/simulator" --help >/dev/null) \
  || fail "pip-installed simulator --help"
(cd "$scratch" && timeout 60 "$scratch/venv/bin/log2bag" --help >/dev/null) \
  || fail "pip-installed log2bag --help"
(cd "$scratch" && timeout 60 "$scratch/venv/bin/monitor" --help >/dev/null) \
  || fail "pip-installed monitor --help"
(cd "$scratch" && timeout 60 "$scratch/venv/bin/probe" --help >/dev/null) \
  || fail "pip-installed probe --help"
(cd "$scratch" && timeout 60 "$scratch/venv/bin/ams-can-bridge" --help | grep -q 'config/\*.yaml') \
  || fail "pip-installed ams-can-bridge --help"
(cd "$scratch" && timeout 60 "$scratch/venv/bin/bridgectl" --help >/dev/null) \
  || fail "pip-installed bridgectl --help"
echo "pip install: OK ($scratch/venv)"
