"""ReadMeter counts what the calls made through it read, to the byte, in any thread."""

import os
import threading

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geoterrain.core.osreads import EXACT, ReadMeter

pytestmark = pytest.mark.skipif(not EXACT, reason="no per-thread I/O counters")


@pytest.fixture(scope="module")
def data_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("osreads") / "data.bin"
    path.write_bytes(os.urandom(1 << 16))
    return path


@settings(max_examples=40, deadline=None)
@given(reads=st.lists(st.tuples(st.integers(0, 1 << 16), st.integers(0, 5000)), max_size=12))
def test_meter_counts_every_byte_read(data_file, reads):
    """Each pread returns what lies in the file (fewer bytes near its end, none past it);
    the meter's count is the sum, and reads outside its calls are not counted."""
    fd = os.open(data_file, os.O_RDONLY)
    try:
        m = ReadMeter()
        got = [m.call(lambda o=off, n=n: len(os.pread(fd, n, o))) for off, n in reads]
        os.pread(fd, 100, 0)  # not through the meter
        assert m.bytes == sum(got) == sum(max(0, min(n, (1 << 16) - off)) for off, n in reads)
    finally:
        os.close(fd)


def test_meter_counts_each_thread_its_own_reads(data_file):
    m = ReadMeter()
    fd = os.open(data_file, os.O_RDONLY)
    try:
        def work(n):
            for _ in range(50):
                m.call(lambda: os.pread(fd, n, 0))

        threads = [threading.Thread(target=work, args=(n,)) for n in (10, 300, 4096)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert m.bytes == 50 * (10 + 300 + 4096)
    finally:
        os.close(fd)
