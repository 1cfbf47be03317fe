"""Python peers of `ground decode` for the decode benchmark, timed on the same file.

usage: py_decode.py spacepackets FILE
       py_decode.py spp XTCE FILE

spacepackets  bare header unpacking: `spacepackets.ecss.tm.PusTm.unpack` per packet
              (primary and secondary header, time stamp, CRC check); the source data
              stays bytes. A reference for what Python does with no MIB at all.
spp           full decode into named values: space-packet-parser (the independent XTCE
              decoder of our CI cross-check) with the MIB's XTCE export, every parameter of
              every packet produced (raw and calibrated).

Prints one line: "<peer>: N packets (B bad) in T s = R packets/s".
"""
import sys
import time
import warnings


def spacepackets_rate(path: str) -> str:
    from spacepackets.ecss.tm import PusTm

    data = open(path, "rb").read()
    n = bad = off = 0
    end = len(data)
    t0 = time.perf_counter()
    while off + 6 <= end:
        plen = ((data[off + 4] << 8) | data[off + 5]) + 7
        try:
            PusTm.unpack(data[off : off + plen], timestamp_len=7)
            n += 1
        except Exception:
            bad += 1
        off += plen
    dt = time.perf_counter() - t0
    return f"python spacepackets (headers only): {n} packets ({bad} bad) in {dt:.2f} s = {n / dt:.0f} packets/s"


def spp_rate(xtce: str, path: str) -> str:
    import logging

    import space_packet_parser as spp

    logging.getLogger("space_packet_parser").setLevel(logging.CRITICAL)
    definition = spp.load_xtce(xtce)
    n = bad = fields = 0
    t0 = time.perf_counter()
    with open(path, "rb") as f:
        for raw in spp.ccsds_generator(f):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")
                    pkt = definition.parse_bytes(bytes(raw))
                fields += len(pkt)
                n += 1
            except Exception:
                bad += 1
    dt = time.perf_counter() - t0
    return (
        f"space-packet-parser (XTCE, named values): {n} packets ({bad} bad, {fields} values) "
        f"in {dt:.2f} s = {n / dt:.0f} packets/s"
    )


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "spacepackets":
        print(spacepackets_rate(sys.argv[2]))
    elif len(sys.argv) == 4 and sys.argv[1] == "spp":
        print(spp_rate(sys.argv[2], sys.argv[3]))
    else:
        print(__doc__)
        sys.exit(2)


if __name__ == "__main__":
    main()
