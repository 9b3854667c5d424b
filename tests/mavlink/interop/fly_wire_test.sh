#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Every byte of a real flight on the wire, decoded by node-mavlink (docs/mavlink.md, "Interop
# test"): `fnmpc sim-link --autopilot px4` and `fnmpc fly` fly config/scenarios/single.yaml
# with MAVLink 2 signing through a UDP relay that records both directions; node-mavlink
# (interop.mjs decode, with the key) then splits and decodes the recordings. It checks what
# our own parser cannot check about our own encoder: no frame node-mavlink rejects (CRC,
# CRC_EXTRA, length), every frame signed with a signature node-mavlink verifies and signing
# timestamps that only grow per link; the frames sim-link writes raw (GLOBAL_POSITION_INT,
# EXTENDED_SYS_STATE, STATUSTEXT) with plausible fields: altitude against LOCAL_POSITION_NED,
# the landed state on ground, in the air and on ground again; the setpoints' quaternions unit
# and their thrust in [0, 1].
# Usage: fly_wire_test.sh FNMPC SOURCE_DIR NODE INTEROP_DIR
set -euo pipefail
fnmpc=$1
src=$2
node=$3
interop=$4
source "$src/tests/apps/link_test_common.sh"

base=$((24000 + ($$ % 1000) * 4))
relay=$((base + 1))
od -An -tx1 -N32 /dev/urandom | tr -d ' \n' > "$work/key.hex"
write_short_scenario "$src" single "$work/single.yaml"

# The relay: fly sends to $relay, the relay forwards to sim-link's $base and back, appending
# each datagram to up.bin (fly -> autopilot) or down.bin (autopilot -> fly).
/usr/bin/python3 - "$relay" "$base" "$work" <<'PY' &
import select, socket, sys
relay, ap_port, work = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
fly_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
fly_side.bind(("127.0.0.1", relay))
ap_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
ap_side.connect(("127.0.0.1", ap_port))
up, down = open(f"{work}/up.bin", "wb"), open(f"{work}/down.bin", "wb")
fly_addr = None
while True:
    for s in select.select([fly_side, ap_side], [], [])[0]:
        if s is fly_side:
            data, fly_addr = fly_side.recvfrom(65536)
            up.write(data); up.flush()
            ap_side.send(data)
        else:
            try:
                data = ap_side.recv(65536)
            except ConnectionRefusedError:  # sim-link not listening yet
                continue
            down.write(data); down.flush()
            if fly_addr:
                fly_side.sendto(data, fly_addr)
PY
pids+=("$!")
"$fnmpc" sim-link "$work/single.yaml" --autopilot px4 --lockstep --port "$base" \
  --signing-key "$work/key.hex" -o "$work/link" --quiet > /dev/null 2> "$work/sim-link.err" &
sim=$!
pids+=("$sim")
"$fnmpc" fly leader "$work/single.yaml" --link "udpout:127.0.0.1:$relay" --autopilot px4 \
  --clock autopilot -o "$work/fly" --quiet --signing-key "$work/key.hex" 2> "$work/fly.err" &
fly=$!
pids+=("$fly")
rc=0
wait "$sim" || rc=$?
[ "$rc" -eq 0 ] || { cat "$work/sim-link.err" >&2; fail "sim-link exited with $rc"; }
rc=0
wait "$fly" || rc=$?
[ "$rc" -eq 0 ] || { cat "$work/fly.err" >&2; fail "fly exited with $rc"; }

key=$(cat "$work/key.hex")
"$node" "$interop/interop.mjs" decode "$work/up.bin" "$key" > "$work/up.json"
"$node" "$interop/interop.mjs" decode "$work/down.bin" "$key" > "$work/down.json"

/usr/bin/python3 - "$work" <<'PY'
import collections, json, math, sys
work = sys.argv[1]
up, down = (json.load(open(f"{work}/{d}.json")) for d in ("up", "down"))


def check_stream(name, rec, bytes_file):
    frames = rec["frames"]
    c = rec["counters"]
    assert frames, f"{name}: no frame decoded"
    assert c["invalid"] == 0 and c["unknown"] == 0, (name, c)
    assert c["valid"] == len(frames), (name, c, len(frames))
    # Every byte of the recording is in a decoded frame: 12 bytes of header and CRC, the
    # payload, 13 bytes of signature.
    size = sum(12 + f["payload_length"] + (13 if f["signature"] else 0) for f in frames)
    with open(bytes_file, "rb") as fh:
        assert size == len(fh.read()), (name, size)
    last = {}
    for f in frames:
        s = f["signature"]
        assert s is not None and s["matches"] is True, (name, f["name"], s)
        link = (f["sysid"], f["compid"], s["link_id"])
        assert s["timestamp"] > last.get(link, -1), (name, link, s["timestamp"], last.get(link))
        last[link] = s["timestamp"]
    names = collections.Counter(f["name"] for f in frames)
    print(f"{name}: {len(frames)} frames, {size} bytes, all signed and verified; "
          + ", ".join(f"{k} {v}" for k, v in sorted(names.items())))
    return names


up_names = check_stream("fly -> autopilot", up, f"{work}/up.bin")
down_names = check_stream("autopilot -> fly", down, f"{work}/down.bin")
for n in ("HEARTBEAT", "SET_ATTITUDE_TARGET", "COMMAND_LONG"):
    assert up_names[n] > 0, (n, up_names)
for n in ("HEARTBEAT", "GLOBAL_POSITION_INT", "EXTENDED_SYS_STATE", "LOCAL_POSITION_NED",
          "COMMAND_ACK", "HIGHRES_IMU"):
    assert down_names[n] > 0, (n, down_names)

# (type_mask bit 7, ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE: the keep-alive setpoints after
# landing carry no attitude.)
for f in up["frames"]:
    if f["name"] == "SET_ATTITUDE_TARGET" and not f["fields"]["type_mask"] & 128:
        q = f["fields"]["q"]
        assert abs(math.sqrt(sum(x * x for x in q)) - 1.0) < 1e-3, q
        assert 0.0 <= f["fields"]["thrust"] <= 1.0, f["fields"]["thrust"]
# GLOBAL_POSITION_INT's relative altitude [mm, up] against the LOCAL_POSITION_NED z [m, down]
# sent just before it; the landed states on ground, in the air, on ground.
ned_z = None
worst = 0.0
top = 0
landed = []
for f in down["frames"]:
    if f["name"] == "LOCAL_POSITION_NED":
        ned_z = f["fields"]["z"]
    elif f["name"] == "GLOBAL_POSITION_INT" and ned_z is not None:
        alt = f["fields"]["relative_alt"]
        top = max(top, alt)
        worst = max(worst, abs(alt / 1000.0 + ned_z))
    elif f["name"] == "EXTENDED_SYS_STATE":
        state = f["fields"]["landed_state"]
        if not landed or landed[-1] != state:
            landed.append(state)
    elif f["name"] == "STATUSTEXT":
        text = f["fields"]["text"]
        assert text and all(32 <= ord(ch) < 127 for ch in text), text
assert 300 <= top <= 3000, f"highest relative_alt {top} mm"
assert worst < 0.5, f"relative_alt and LOCAL_POSITION_NED z apart by up to {worst:.3f} m"
assert landed[0] == 1 and 2 in landed and landed[-1] == 1, landed
print(f"highest relative_alt {top} mm, within {worst:.3f} m of LOCAL_POSITION_NED; "
      f"landed states {landed}")
PY
