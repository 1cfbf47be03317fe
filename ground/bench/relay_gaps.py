#!/usr/bin/env python3
"""What the relay saw of one run: did the obsw stop sending, or did its frames stop reaching
the ground?

    relay_gaps.py TRACE T0 T1

TRACE: the relay's `--trace` file (one line per UDP datagram: `UNIX_US up|down LEN FATE
HEAD`, FATE `drop` or one letter per copy sent, `o` intact, `x` corrupted). T0, T1: the
ground command's start and end (Unix seconds, as `date +%s.%N`).

Prints one line `relay: ...` with, within T0..T1:
- `obsw gap`: the longest time between two TM frames the relay took from the obsw (the
  obsw sends one at least every 100 ms; a long gap followed by a burst of frames read at
  once means the relay was not scheduled, one followed by the usual cadence means the obsw
  sent nothing), where it ended (seconds after T0) and how many frames the relay read in
  the 5 ms after it;
- `intact gap`: the longest time between two frames forwarded intact to the ground (what a
  ground that read every datagram at once would call its silence), and where it ended;
- `end`: the time from the last intact frame forwarded (before T1, in the window or not)
  to T1 (a ground that ends on a loss states about this silence if the relay is right);
- the counts of TC frames up and TM frames down.
Exits 0; 2 on unreadable input.
"""
import sys


def main():
    if len(sys.argv) != 4:
        print(__doc__, file=sys.stderr)
        return 2
    path, t0, t1 = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    down, intact, up = [], [], 0
    try:
        with open(path) as f:
            for line in f:
                parts = line.split()
                if len(parts) < 4:
                    continue
                t = int(parts[0]) / 1e6
                if parts[1] == "up":
                    up += t0 <= t <= t1
                    continue
                down.append(t)
                if "o" in parts[3]:
                    intact.append(t)
    except (OSError, ValueError) as e:
        print(f"relay: trace unreadable: {e}")
        return 2

    def longest(ts):
        ts = [t for t in ts if t0 <= t <= t1]
        best = (0.0, None)
        for a, b in zip(ts, ts[1:]):
            if b - a > best[0]:
                best = (b - a, b)
        return best, ts

    (og, og_end), in_run = longest(down)
    burst = sum(1 for t in in_run if og_end is not None and og_end <= t <= og_end + 0.005)
    (ig, ig_end), intact_run = longest(intact)
    # The last intact frame before T1, however long before T0 (the silent case's T0 is the
    # moment the obsw was stopped: its last frames came before).
    before = [t for t in intact if t <= t1]
    end = t1 - before[-1] if before else float("nan")

    def at(t):
        return f"+{t - t0:.1f} s" if t is not None else "-"

    print(
        f"relay: obsw gap {og:.2f} s ending {at(og_end)} ({burst} read in 5 ms after); "
        f"intact gap {ig:.2f} s ending {at(ig_end)}; end {end:.2f} s after the last intact; "
        f"{up} TC frames up, {len(in_run)} TM frames down"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
