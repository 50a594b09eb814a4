"""Decodes a python-can log of a `flexid sweep` with python-can's own LogReader (not
flexid's code) and prints what the cycle traffic was, one `key value` line each.

Usage: decode_sweep_log.py LOG NODE_ID

Cycle k on the wire, as CiA 301/402 and flexid's default mapping say: RPDO1 (0x200+id:
controlword u16, target torque i16 per-mille) from the master, SYNC (0x080, no data), then
the drive's TPDO1 (0x180+id: statusword u16, position i32, torque i16) and TPDO2
(0x280+id: velocity i32) answering that SYNC.
"""
import struct
import sys

import can


def main():
    path, node = sys.argv[1], int(sys.argv[2])
    sync, rpdo1, tpdo1, tpdo2 = 0x080, 0x200 + node, 0x180 + node, 0x280 + node
    msgs = [m for m in can.LogReader(path) if not m.is_error_frame]
    # In the order the host received them: python-can's udp_multicast stamps each frame
    # with the kernel's receive time (SO_TIMESTAMP). The log itself is in the order the
    # logger's socket queued them, and multicast loopback delivers to each socket from the
    # sending CPU's backlog: a SYNC received first can reach the logger's queue after the
    # drive's answer to it (seen: 25 of 1254 cycles). Stable sort: equal stamps keep order.
    msgs.sort(key=lambda m: m.timestamp)
    kinds = []
    for m in msgs:
        k = {sync: "S", rpdo1: "R", tpdo1: "T1", tpdo2: "T2"}.get(m.arbitration_id)
        if k:
            kinds.append((k, m))
    n_sync = sum(1 for k, _ in kinds if k == "S")
    print(f"sync {n_sync}")
    print(f"rpdo1 {sum(1 for k, _ in kinds if k == 'R')}")
    print(f"tpdo1 {sum(1 for k, _ in kinds if k == 'T1')}")
    print(f"tpdo2 {sum(1 for k, _ in kinds if k == 'T2')}")
    # Between two SYNCs of the excitation: one RPDO1 before the SYNC, and the two TPDOs
    # after it. Count the cycles that follow exactly R S T1 T2 (the TPDO order may swap).
    ordered = 0
    seq = [k for k, _ in kinds]
    for i in range(1, len(seq) - 2):
        if seq[i] == "S" and seq[i - 1] == "R" and sorted(seq[i + 1:i + 3]) == ["T1", "T2"]:
            ordered += 1
    print(f"ordered_cycles {ordered}")
    bad_len = sum(1 for k, m in kinds if (k == "S" and m.dlc != 0) or (k == "R" and m.dlc != 4)
                  or (k == "T1" and m.dlc != 8) or (k == "T2" and m.dlc != 4))
    print(f"bad_dlc {bad_len}")
    # Operation enabled (statusword & 0x6F == 0x27) in the TPDO1s, and torque commands.
    enabled = sum(1 for k, m in kinds if k == "T1"
                  and struct.unpack_from("<H", m.data)[0] & 0x6F == 0x27)
    print(f"tpdo1_operation_enabled {enabled}")
    torques = [struct.unpack_from("<Hh", m.data)[1] for k, m in kinds if k == "R"]
    nonzero = sum(1 for t in torques if t != 0)
    print(f"rpdo1_nonzero_torque {nonzero}")
    print(f"rpdo1_max_abs_permille {max((abs(t) for t in torques), default=0)}")
    positions = [struct.unpack_from("<Hi", m.data)[1] for k, m in kinds if k == "T1"]
    print(f"position_span_increments {max(positions) - min(positions) if positions else 0}")


if __name__ == "__main__":
    main()
