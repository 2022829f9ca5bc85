#!/usr/bin/env python3
"""An outside CANopen master (python `canopen` over slcan) reads the mandatory CiA 301 objects of
every drive of rigcal's table emulator: 0x1000 device type (402 = 0x0192 in the low word),
0x1001 error register and 0x1018 identity.

Install: pip install canopen python-can pyserial
Usage:   scripts/canopen-master.py [RIG.toml]   (default rigs/rv-m2.toml; builds nothing: run
         `cargo build --release` first, or set RIGCAL to the binary)
"""
import os
import subprocess
import sys

import canopen

rig = sys.argv[1] if len(sys.argv) > 1 else "rigs/rv-m2.toml"
rigcal = os.environ.get("RIGCAL", "target/release/rigcal")
emulator = subprocess.Popen([rigcal, "sim-device", "table", "--rig", rig, "--pty"],
                            stdout=subprocess.PIPE, text=True)
try:
    pty = emulator.stdout.readline().strip()
    print(f"table emulator on {pty}")
    network = canopen.Network()
    network.connect(interface="slcan", channel=pty, bitrate=500000)
    failed = False
    for node_id in (1, 2, 3):
        node = network.add_node(node_id, canopen.ObjectDictionary())
        node.sdo.RESPONSE_TIMEOUT = 2.0
        device_type = int.from_bytes(node.sdo.upload(0x1000, 0), "little")
        error_register = int.from_bytes(node.sdo.upload(0x1001, 0), "little")
        identity = [int.from_bytes(node.sdo.upload(0x1018, sub), "little") for sub in range(5)]
        profile = device_type & 0xFFFF
        print(f"node {node_id}: 0x1000 = {device_type:#010x} (profile {profile}), "
              f"0x1001 = {error_register:#04x}, 0x1018 = {identity[0]} entries, vendor "
              f"{identity[1]:#010x}, product {identity[2]:#010x}, revision {identity[3]:#010x}, "
              f"serial {identity[4]}")
        failed |= profile != 402
    network.disconnect()
    sys.exit(1 if failed else 0)
finally:
    emulator.kill()
