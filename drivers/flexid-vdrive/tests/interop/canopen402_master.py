"""python-canopen (an implementation no one on flexid wrote) as the master of flexid-vdrive.

Usage: canopen402_master.py GROUP PORT NODE_ID EDS

Joins python-can's udp_multicast bus, and with canopen's BaseNode402:
NMT reset -> boot-up, SDO reads (expedited 0x1018, segmented 0x1008), SDO write/read
0x6060, PDO configuration uploaded by SDO, SYNC at 100 Hz, the CiA 402 state machine walked
to OPERATION ENABLED through the RPDO controlword, a target torque through the RPDO and the
motor's response in the TPDOs, back to SWITCH ON DISABLED; then, enabled again with the
drive's heartbeat consumer watching this master, the master's heartbeat stops: the drive
must fault (EMCY 0x8130 received through canopen's EMCY consumer, state FAULT).

Prints one `key value` line per check; the Rust test asserts them. Exit code 0 only when the
whole sequence ran.
"""
import sys
import threading
import time

import canopen


def say(key, value):
    print(f"{key} {value}", flush=True)


def main():
    group, port, node_id, eds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    net = canopen.Network()
    net.connect(interface="udp_multicast", channel=group, port=port)
    try:
        node = canopen.BaseNode402(node_id, eds)
        net.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 1.0

        # wait_for_bootup() only sees a boot-up that arrives after it started waiting, and
        # this drive boots at once: listen first, then reset.
        booted = []
        listener = threading.Thread(
            target=lambda: booted.append(node.nmt.wait_for_bootup(5) is None))
        listener.start()
        time.sleep(0.2)
        node.nmt.state = "RESET"
        listener.join()
        say("bootup", "ok" if booted else "timeout")

        say("device_type", hex(node.sdo[0x1000].raw))
        say("vendor_id", hex(node.sdo[0x1018][1].raw))
        say("product_code", hex(node.sdo[0x1018][2].raw))
        say("device_name", node.sdo[0x1008].raw)  # 13 bytes: segmented upload

        node.sdo[0x6060].raw = 10  # cyclic synchronous torque
        say("mode_display", node.sdo[0x6061].raw)
        say("rated_torque_mnm", node.sdo[0x6076].raw)

        node.nmt.state = "PRE-OPERATIONAL"
        node.setup_402_state_machine(read_pdos=True)
        say("tpdo1", ",".join(hex(v.index) for v in node.tpdo[1]))
        say("rpdo1", ",".join(hex(v.index) for v in node.rpdo[1]))

        node.rpdo[1]["Target torque"].raw = 0
        node.rpdo[1].start(0.01)
        net.sync.start(0.01)
        node.nmt.state = "OPERATIONAL"
        time.sleep(0.1)

        node.state = "SWITCH ON DISABLED"
        say("state0", node.state.replace(" ", "_"))
        node.state = "OPERATION ENABLED"
        say("state1", node.state.replace(" ", "_"))

        node.tpdo[1].wait_for_reception(1.0)
        p0 = node.tpdo[1]["Position actual value"].raw
        node.rpdo[1]["Target torque"].raw = 200  # 20 % of the rated torque
        node.rpdo[1].update()
        t_end = time.monotonic() + 1.0
        while time.monotonic() < t_end:
            node.tpdo[1].wait_for_reception(0.1)
        p1 = node.tpdo[1]["Position actual value"].raw
        v1 = node.tpdo[2]["Velocity actual value"].raw
        tq = node.tpdo[1]["Torque actual value"].raw
        say("moved_increments", p1 - p0)
        say("velocity_increments_s", v1)
        say("torque_actual_permille", tq)

        node.rpdo[1]["Target torque"].raw = 0
        node.rpdo[1].update()
        node.state = "SWITCH ON DISABLED"
        say("state2", node.state.replace(" ", "_"))

        # A dead master must stop the motor: this master (node-id 127) produces a heartbeat
        # every 100 ms, the drive consumes it with 400 ms; then the heartbeat stops.
        node.nmt.state = "PRE-OPERATIONAL"
        node.sdo[0x1016][1].raw = (127 << 16) | 400
        heartbeat = net.send_periodic(0x700 + 127, [0x05], 0.1)
        node.nmt.state = "OPERATIONAL"
        node.state = "OPERATION ENABLED"
        time.sleep(0.6)
        say("state3", node.state.replace(" ", "_"))
        heartbeat.stop()
        t_stop = time.monotonic()
        while node.state != "FAULT" and time.monotonic() < t_stop + 2.0:
            node.tpdo[1].wait_for_reception(0.05)
        say("state4", node.state.replace(" ", "_"))
        say("fault_after_ms", int(1000 * (time.monotonic() - t_stop)))
        codes = [hex(e.code) for e in node.emcy.log]
        say("emcy", ",".join(codes) if codes else "none")
        net.sync.stop()
        node.rpdo[1].stop()
        node.nmt.state = "PRE-OPERATIONAL"
        say("done", "ok")
    finally:
        net.disconnect()


if __name__ == "__main__":
    main()
