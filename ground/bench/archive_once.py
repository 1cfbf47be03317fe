#!/usr/bin/env python3
"""Is every TM packet the obsw sent for a run in the ground's archive exactly once?

    archive_once.py TM_LOG ARCHIVE ROBOT [FROM UPTO]

TM_LOG: the obsw's `--tm-log` (one hex line per TM packet handed to the downlink; a packet
replayed from the on-board store is logged again, so the log's distinct packets are what the
robot sent). ARCHIVE: the ground's SQLite archive. FROM, UPTO: the run's TM range as its
summary states it ("TM robot N: complete from seq FROM up to seq UPTO"); without them only
the archive's own side is checked.

Checks, from the obsw's log as the judge (not from the ground's own accounting):
- every distinct packet the obsw logged with a sequence count in FROM..=UPTO is in the
  archive's `packet` table, byte for byte, exactly once (no row with the same bytes twice,
  no second row for the same sequence count);
- every packet the archive holds for ROBOT is one the obsw logged (nothing forged, corrupted
  or mixed up reached the archive).

Prints one line `archive: ...` and exits 0 when all hold, 1 otherwise.
"""
import collections
import sqlite3
import sys


def seq_of(raw):
    return ((raw[2] << 8) | raw[3]) & 0x3FFF


def in_range(seq, lo, hi):
    # Sequence counts are 14 bits and wrap.
    return (seq - lo) % 0x4000 <= (hi - lo) % 0x4000


def main():
    if len(sys.argv) not in (4, 6):
        sys.exit(__doc__)
    log_path, db_path, robot = sys.argv[1], sys.argv[2], int(sys.argv[3])
    rng = (int(sys.argv[4]), int(sys.argv[5])) if len(sys.argv) == 6 else None

    logged = set()
    with open(log_path) as f:
        for line in f:
            line = line.strip()
            if line:
                logged.add(bytes.fromhex(line))

    db = sqlite3.connect(f"file:{db_path}?mode=ro", uri=True)
    rows = [bytes(r[0]) for r in db.execute("SELECT raw FROM packet WHERE robot = ?", (robot,))]
    by_raw = collections.Counter(rows)
    by_seq = collections.Counter(seq_of(r) for r in rows)

    problems = []
    twice = [r for r, n in by_raw.items() if n > 1]
    if twice:
        problems.append(f"{len(twice)} packets archived more than once")
    foreign = [r for r in by_raw if r not in logged]
    if foreign:
        seqs = sorted(seq_of(r) for r in foreign)[:8]
        problems.append(f"{len(foreign)} archived packets the obsw never sent (seq {seqs})")
    wanted = 0
    if rng is not None:
        lo, hi = rng
        want = [p for p in logged if in_range(seq_of(p), lo, hi)]
        wanted = len(want)
        missing = sorted(seq_of(p) for p in want if by_raw[p] == 0)
        if missing:
            problems.append(f"{len(missing)} of {wanted} logged packets in {lo}..={hi} not archived (seq {missing[:8]})")
        expected = (hi - lo) % 0x4000 + 1
        if wanted != expected:
            problems.append(f"the obsw logged {wanted} distinct packets in {lo}..={hi}, not {expected}")
        doubled = [s for s in range(expected) if by_seq[(lo + s) % 0x4000] > 1]
        if doubled:
            problems.append(f"{len(doubled)} sequence counts in {lo}..={hi} archived more than once")
    span = f"seq {rng[0]}..={rng[1]}: {wanted} logged, " if rng else ""
    verdict = "exactly once" if not problems else "NOT exactly once: " + "; ".join(problems)
    print(f"archive: {span}{len(rows)} archived for robot {robot}, {len(logged)} distinct logged: {verdict}")
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
