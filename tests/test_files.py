"""Result files are replaced whole: a failed write leaves the earlier file, a link is written through;
cache entries are replaced whole, by threads at once too."""
from __future__ import annotations

import errno
import os
import threading

import pytest

from deltafmi.files import USER_FILE_MODE, keep_in_cache, replaced_atomically


def _write(path, text):
    with replaced_atomically(path) as temporary:
        temporary.write_text(text)


def test_a_file_is_replaced_with_the_user_s_permissions(tmp_path):
    target = tmp_path / "out" / "run.csv"
    _write(target, "1\n")
    _write(target, "2\n")
    assert target.read_text() == "2\n"
    assert target.stat().st_mode & 0o777 == USER_FILE_MODE
    assert sorted(p.name for p in target.parent.iterdir()) == ["run.csv"]


def test_a_failed_write_keeps_the_earlier_file_and_leaves_no_part_file(tmp_path):
    target = tmp_path / "run.csv"
    target.write_text("earlier\n")
    with pytest.raises(RuntimeError):
        with replaced_atomically(target) as temporary:
            temporary.write_text("half")
            raise RuntimeError("the run failed")
    assert target.read_text() == "earlier\n"
    assert [p.name for p in tmp_path.iterdir()] == ["run.csv"]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_write_the_disk_refuses_names_the_file_it_was_for(tmp_path):
    target = tmp_path / "model.fmu"
    with pytest.raises(OSError) as failed:
        with replaced_atomically(target):
            with open("/dev/full", "wb", buffering=0) as full:  # the kernel's ENOSPC, no file name
                full.write(b"x")
    assert failed.value.errno == errno.ENOSPC and failed.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []


def test_an_error_naming_the_temporary_file_names_the_file_it_was_for(tmp_path):
    """A writer that opens the temporary file by its name (a zip library) reports that name: the
    user is told the file they asked for."""
    target = tmp_path / "tree.zip"
    with pytest.raises(OSError) as failed:
        with replaced_atomically(target) as part:
            raise OSError(errno.ENOSPC, "No space left on device", str(part))
    assert failed.value.filename == str(target)


def test_a_symbolic_link_is_written_through_and_stays_a_link(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "run.csv").write_text("old\n")
    link = tmp_path / "run.csv"
    link.symlink_to(data / "run.csv")
    _write(link, "new\n")
    assert link.is_symlink() and os.readlink(link) == str(data / "run.csv")
    assert (data / "run.csv").read_text() == "new\n"
    assert sorted(p.name for p in data.iterdir()) == ["run.csv"]  # the temporary was made beside the target


def test_a_dangling_link_makes_its_target(tmp_path):
    link = tmp_path / "run.csv"
    link.symlink_to(tmp_path / "elsewhere.csv")
    _write(link, "new\n")
    assert link.is_symlink() and (tmp_path / "elsewhere.csv").read_text() == "new\n"


def test_a_temporary_file_left_between_enter_and_block_is_removed_when_the_process_ends(tmp_path):
    # a signal's KeyboardInterrupt can land in contextlib's __enter__ after the file was made and
    # before the block (and its finally) starts: the process's exit removes the file
    import subprocess
    import sys

    target = tmp_path / "run.csv"
    code = ("import sys; from pathlib import Path; from deltafmi.files import replaced_atomically\n"
            "manager = replaced_atomically(Path(sys.argv[1])); part = manager.__enter__()\n"
            "assert part.exists(); print(part); raise SystemExit(130)")
    done = subprocess.run([sys.executable, "-c", code, str(target)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 130, done.stderr
    assert done.stdout.strip().endswith(".part")
    assert list(tmp_path.iterdir()) == []


def test_cache_entries_kept_by_threads_at_once_are_each_whole(tmp_path):
    # eight threads of one process replace the same entry with their own 1 MB, again and again,
    # while it is read: every read is one thread's whole entry, and no temporary file is left
    entry = tmp_path / "cache" / "entry"
    payloads = [bytes([i]) * 1_000_000 for i in range(8)]
    start = threading.Barrier(len(payloads) + 1)
    kept = []

    def keep(data):
        start.wait()
        kept.extend(keep_in_cache(entry, data) for _ in range(20))

    threads = [threading.Thread(target=keep, args=(data,)) for data in payloads]
    for thread in threads:
        thread.start()
    start.wait()
    reads = []
    while any(thread.is_alive() for thread in threads):
        if entry.exists():
            reads.append(entry.read_bytes())
    for thread in threads:
        thread.join()
    reads.append(entry.read_bytes())
    assert all(kept) and len(kept) == 160
    assert all(data in payloads for data in reads)
    assert [p.name for p in entry.parent.iterdir()] == ["entry"]


def test_a_cache_entry_that_cannot_be_written_is_not_kept(tmp_path):
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache's folder would be")
    assert keep_in_cache(blocker / "entry", b"data") is False
    assert [p.name for p in tmp_path.iterdir()] == ["cache"]
