"""Decode a file of concatenated PUS-C TM packets with the Python `spacepackets`
package (CRC checked by PusTm.unpack) and unpack the HK source data with `struct`,
the same work `ground decode --summary` does. Prints packets/s.

usage: py_decode.py FILE STRUCT_FORMAT
"""
import struct
import sys
import time

from spacepackets.ecss.tm import PusTm


def main() -> None:
    path, fmt = sys.argv[1], sys.argv[2]
    data = open(path, "rb").read()
    hk = struct.Struct(fmt)
    n = bad = 0
    off = 0
    t0 = time.perf_counter()
    end = len(data)
    while off + 6 <= end:
        plen = ((data[off + 4] << 8) | data[off + 5]) + 7
        raw = data[off : off + plen]
        try:
            tm = PusTm.unpack(raw, timestamp_len=7)
            values = hk.unpack(tm.source_data)
            n += 1
        except Exception:
            bad += 1
        off += plen
    dt = time.perf_counter() - t0
    print(f"python spacepackets: {n} packets ({bad} bad) in {dt:.2f} s = {n / dt:.0f} packets/s")


if __name__ == "__main__":
    main()
