"""An independent CFDP entity (Python `cfdp`, librecube) over UDP PDUs, for
obsw/cfdp/tests/interop.rs: it puts the files it is told to, class 1 and class 2, to the
entity on the other port, and keeps receiving what that entity puts to it, until the file
STOP appears in its folder.

usage: cfdp_peer.py MY_ID MY_PORT PEER_ID PEER_PORT FOLDER [CLASS:SRC:DEST ...]
Prints one line per put: `put SRC DEST done` once the transaction completed.
"""
import os
import sys
import time

import cfdp
from cfdp.constants import TransmissionMode
from cfdp.filestore import NativeFileStore
from cfdp.transport.udp import UdpTransport


def main():
    my_id, my_port, peer_id, peer_port, folder = sys.argv[1:6]
    puts = [a.split(":") for a in sys.argv[6:]]
    transport = UdpTransport(routing={"*": [("127.0.0.1", int(peer_port))]})
    transport.bind("127.0.0.1", int(my_port))
    entity = cfdp.CfdpEntity(
        entity_id=int(my_id),
        filestore=NativeFileStore(folder),
        transport=transport,
        positive_ack_timer_interval=2,
        nak_timer_interval=2,
    )
    try:
        print("ready", flush=True)
        for cls, src, dest in puts:
            mode = TransmissionMode.UNACKNOWLEDGED if cls == "1" else TransmissionMode.ACKNOWLEDGED
            tid = entity.put(
                destination_id=int(peer_id),
                source_filename=src,
                destination_filename=dest,
                transmission_mode=mode,
            )
            deadline = time.time() + 60
            while not entity.is_complete(tid) and time.time() < deadline:
                time.sleep(0.05)
            print(f"put {src} {dest} {'done' if entity.is_complete(tid) else 'TIMEOUT'}", flush=True)
        deadline = time.time() + 120
        while not os.path.exists(os.path.join(folder, "STOP")) and time.time() < deadline:
            time.sleep(0.05)
    finally:
        entity.shutdown()
        transport.unbind()


if __name__ == "__main__":
    main()
