"""Baseline for ground/bench/archive_bench.sh: Python's sqlite3 storing bare packets as
rows (one row per packet with its key columns and the raw bytes, a UNIQUE key so that a
re-import adds nothing), and answering one-parameter questions by decoding the packets.

usage:
  py_archive.py ingest FILE DB                      prints "N packets in S s"
  py_archive.py export DB FMT FIELD SCALE OFFSET OUT   one parameter of every HK packet as CSV
  py_archive.py query DB FMT FIELD SCALE OFFSET T0 T1  the same over [T0, T1] (on-board ms)
"""
import sqlite3
import struct
import sys
import time

CCSDS_TO_UNIX_MS = 4383 * 86_400_000
SCHEMA = """
CREATE TABLE IF NOT EXISTS packet (
    id INTEGER PRIMARY KEY, robot INTEGER NOT NULL, apid INTEGER NOT NULL, seq INTEGER NOT NULL,
    obt_ms INTEGER NOT NULL, t_ms INTEGER NOT NULL, raw BLOB NOT NULL,
    UNIQUE (robot, apid, obt_ms, seq));
"""


def packets(data):
    off, end = 0, len(data)
    while off + 6 <= end:
        plen = ((data[off + 4] << 8) | data[off + 5]) + 7
        yield data[off : off + plen]
        off += plen


def key(raw, robot, now):
    apid = ((raw[0] << 8) | raw[1]) & 0x7FF
    seq = ((raw[2] << 8) | raw[3]) & 0x3FFF
    days, ms = struct.unpack_from(">HI", raw, 14)
    return (robot, apid, seq, days * 86_400_000 + ms - CCSDS_TO_UNIX_MS, now, raw)


def ingest(path, db):
    data = open(path, "rb").read()
    t0 = time.perf_counter()
    c = sqlite3.connect(db)
    c.execute("PRAGMA journal_mode=WAL")
    c.execute("PRAGMA synchronous=NORMAL")
    c.executescript(SCHEMA)
    now = int(time.time() * 1000)
    rows = (key(raw, 1, now) for raw in packets(data))
    before = c.total_changes
    with c:
        c.executemany(
            "INSERT OR IGNORE INTO packet (robot, apid, seq, obt_ms, t_ms, raw) VALUES (?, ?, ?, ?, ?, ?)", rows
        )
    stored = c.total_changes - before
    c.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    c.close()
    print(f"{stored} packets stored in {time.perf_counter() - t0:.3f} s")


def values(c, fmt, field, scale, offset, where="", args=()):
    hk = struct.Struct(fmt)
    for obt, raw in c.execute(f"SELECT obt_ms, raw FROM packet {where} ORDER BY obt_ms", args):
        if raw[7] == 3 and raw[8] == 25:
            v = hk.unpack_from(raw, 20)[field]
            yield obt, v, v * scale + offset


def export(db, fmt, field, scale, offset, out):
    t0 = time.perf_counter()
    c = sqlite3.connect(db)
    n = 0
    with open(out, "w") as f:
        f.write("t_ms,raw,eng\n")
        for obt, v, e in values(c, fmt, field, scale, offset):
            f.write(f"{obt},{v},{e}\n")
            n += 1
    print(f"{n} rows in {time.perf_counter() - t0:.3f} s")


def query(db, fmt, field, scale, offset, t_lo, t_hi):
    t0 = time.perf_counter()
    c = sqlite3.connect(db)
    n = sum(1 for _ in values(c, fmt, field, scale, offset, "WHERE obt_ms BETWEEN ? AND ?", (t_lo, t_hi)))
    print(f"{n} rows in {time.perf_counter() - t0:.3f} s")


if __name__ == "__main__":
    a = sys.argv[1:]
    if a[0] == "ingest":
        ingest(a[1], a[2])
    elif a[0] == "export":
        export(a[1], a[2], int(a[3]), float(a[4]), float(a[5]), a[6])
    elif a[0] == "query":
        query(a[1], a[2], int(a[3]), float(a[4]), float(a[5]), int(a[6]), int(a[7]))
    else:
        sys.exit(__doc__)
