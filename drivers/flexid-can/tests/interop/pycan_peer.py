"""python-can peer for tests/udp_interop.rs.

Usage: pycan_peer.py GROUP PORT N

Opens can.Bus(interface="udp_multicast", channel=GROUP, port=PORT), prints "ready",
receives N frames (sent by Rust), printing each as "rx ID EXT RTR DLC DATAHEX", then
answers every frame with one of its own (id + 1 for data frames, data reversed) and
prints "done". python-can receives its own frames too: those are told apart by id
(the answers use ids the Rust side never sends).
"""

import sys

import can

group, port, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
bus = can.Bus(interface="udp_multicast", channel=group, port=port)
try:
    print("ready", flush=True)
    got = []
    while len(got) < n:
        msg = bus.recv(10.0)
        if msg is None:
            print(f"timeout after {len(got)} frames", flush=True)
            sys.exit(1)
        got.append(msg)
        print(
            f"rx {msg.arbitration_id:x} {int(msg.is_extended_id)} "
            f"{int(msg.is_remote_frame)} {msg.dlc} {bytes(msg.data).hex()}",
            flush=True,
        )
    for msg in got:
        if msg.is_remote_frame:
            answer = can.Message(
                arbitration_id=msg.arbitration_id | 0x80 if not msg.is_extended_id else msg.arbitration_id + 1,
                is_extended_id=msg.is_extended_id,
                data=bytes(range(msg.dlc)),
            )
        else:
            answer = can.Message(
                arbitration_id=msg.arbitration_id + 1,
                is_extended_id=msg.is_extended_id,
                data=bytes(reversed(msg.data)),
            )
        bus.send(answer)
    print("done", flush=True)
finally:
    bus.shutdown()
