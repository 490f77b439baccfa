"""comat.heap: freed heap pages go back to the OS (Linux, glibc)."""

import sys

import pytest

from comat.bench.soak import _rss_bytes
from comat.heap import release_free_heap


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_release_free_heap_returns_pages_that_free_alone_keeps():
    # 60 MB of small blocks on the heap, then all freed but every 100th and the last: the free
    # pages lie between live blocks, so free() alone cannot shrink the heap.
    blocks = [bytearray(3000) for _ in range(20_000)]
    keep = blocks[::100] + blocks[-1:]
    del blocks
    before = _rss_bytes()
    assert release_free_heap() is True
    after = _rss_bytes()
    assert before - after > 20 * 2**20, (before / 2**20, after / 2**20)
    assert len(keep) == 201
