"""Usage: python benchmarks/diag/soak_memory_trace.py OUT.json EPISODES  (issue 21)

The soak's episodes (``comat bench soak --sets train test scale``, seed 0). After every batch:
RSS after trim and glibc's in-use bytes (live malloc: a rising in-use is a leak, a flat one under
rising RSS is fragmentation). Every 50 batches (1,000 episodes) a tracemalloc snapshot, diffed
against the first (Python and numpy allocations by source line), printed and written to OUT.json.
"""

import ctypes
import json
import sys
import tracemalloc
from pathlib import Path

from comat import heap
from comat.bench import soak


class MallInfo2(ctypes.Structure):
    _fields_ = [
        (n, ctypes.c_size_t)
        for n in (
            "arena",
            "ordblks",
            "smblks",
            "hblks",
            "hblkhd",
            "usmblks",
            "fsmblks",
            "uordblks",
            "fordblks",
            "keepcost",
        )
    ]


libc = ctypes.CDLL("libc.so.6")
libc.mallinfo2.restype = MallInfo2
real_release, rows, first = heap.release_free_heap, [], []
out = Path(sys.argv[1])


def sample_after_release():
    real_release()
    m = libc.mallinfo2()
    row = {
        "batch": len(rows) + 1,
        "rss": soak._rss_bytes(),
        "in_use": m.uordblks + m.hblkhd,
        "traced": tracemalloc.get_traced_memory()[0],
    }
    rows.append(row)
    if len(rows) % 50 == 10:
        snap = tracemalloc.take_snapshot().filter_traces([tracemalloc.Filter(False, tracemalloc.__file__)])
        if not first:
            first.append(snap)
        row["growth"] = [
            (str(s.traceback), s.size_diff, s.count_diff) for s in snap.compare_to(first[0], "lineno")[:15]
        ]
        print(
            row["batch"], {k: round(v / 2**20, 1) for k, v in row.items() if k not in ("batch", "growth")}, flush=True
        )
        for line in row["growth"][:8]:
            print("   ", line, flush=True)
        out.write_text(json.dumps(rows))
    return True


heap.release_free_heap = sample_after_release
tracemalloc.start(1)
soak.run_soak(int(sys.argv[2]), sets=("train", "test", "scale"), progress=print)
out.write_text(json.dumps(rows))
