#!/usr/bin/env python3
"""cornell-ring.py CSV: issue #13's "ceiling ring beside the light" of
scenes/cornell.json at 256 px, from `radray-exr-error TEST.exr REF.exr 4
--blocks CSV` (4 x 4 blocks): the ceiling's blocks in columns 22..41 and rows
3..13 around the lamp's own 12 x 4 blocks (columns 26..37, rows 7..10; the
lamp's edge blocks are part of the lamp), 172 blocks. Prints the mean and the
largest |error| over them and the signed mean. Exit status 2 on a CSV that is
not a 256 px Cornell box's."""
import csv
import sys


def main():
    if len(sys.argv) != 2:
        print("usage: cornell-ring.py BLOCKS.csv", file=sys.stderr)
        return 2
    err = {}
    try:
        with open(sys.argv[1], newline="") as f:
            for row in csv.reader(f):
                bx, by, _, e = row
                err[(int(bx), int(by))] = float(e) if e else None
    except (OSError, ValueError) as ex:
        print("cornell-ring.py: %s: %s" % (sys.argv[1], ex), file=sys.stderr)
        return 2
    ring = [(x, y) for x in range(22, 42) for y in range(3, 14) if not (26 <= x <= 37 and 7 <= y <= 10)]
    vals = [err.get(k) for k in ring]
    if max(x for x, _ in err) != 63 or any(v is None for v in vals):
        print("cornell-ring.py: %s: not 4 x 4 blocks of a 256 px Cornell box" % sys.argv[1], file=sys.stderr)
        return 2
    a = [abs(v) for v in vals]
    print("ring_blocks=%d mean_abs=%.4f max_abs=%.4f mean=%+.4f" % (len(a), sum(a) / len(a), max(a), sum(vals) / len(vals)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
