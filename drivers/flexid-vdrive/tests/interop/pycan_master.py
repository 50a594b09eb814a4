"""A python-can peer acting as a minimal CANopen master against flexid-vdrive.

Usage: pycan_master.py GROUP PORT NODE
Prints one line per check: "boot 00", "sdo 1000 43001000920102 00", ... (hex payloads),
then "done". Only python-can (udp_multicast); the CANopen frames are built by hand.
"""
import sys
import time

import can

group, port, node = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
bus = can.Bus(interface="udp_multicast", channel=group, port=port, receive_own_messages=False)


def recv(cob, timeout=3.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m = bus.recv(timeout=max(0.0, end - time.monotonic()))
        if m is not None and m.arbitration_id == cob and not m.is_extended_id:
            return bytes(m.data)
    print(f"timeout {cob:03x}", flush=True)
    sys.exit(1)


def send(cob, data):
    bus.send(can.Message(arbitration_id=cob, data=bytes(data), is_extended_id=False))


send(0x000, [0x81, node])
print("boot", recv(0x700 + node).hex(), flush=True)
send(0x600 + node, [0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0])
print("sdo1000", recv(0x580 + node).hex(), flush=True)
# NMT start, enable with 0.25 N m (250 per-mille), two SYNCs: TPDO1 of the second one.
send(0x000, [0x01, node])
for cw in (0x06, 0x07, 0x0F):
    send(0x200 + node, [cw, 0, 0xFA, 0x00])
time.sleep(0.05)
send(0x080, [])
first = recv(0x180 + node)
send(0x080, [])
second = recv(0x180 + node)
print("tpdo1", first.hex(), second.hex(), flush=True)
bus.shutdown()
print("done", flush=True)
