"""Atomic writes and the up-front output check shared by every command."""
import ctypes
import os
import signal
import threading
import time

import pytest

from twolink.artifacts import Terminated, atomic_path, check_outputs, sigterm_raises


def test_check_outputs_accepts_distinct_writable_files(tmp_path):
    out = check_outputs({"--csv": tmp_path / "a.csv", "--npz": None,
                         "--figure": tmp_path / "a.png"})
    assert out == {"--csv": tmp_path / "a.csv", "--figure": tmp_path / "a.png"}
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("outputs, message", [
    ({"--csv": "{tmp}/x.png", "--figure": "{tmp}/x.png"}, "--csv and --figure both write"),
    ({"--csv": "{tmp}/x.png", "--figure": "{tmp}/sub/../x.png"}, "--csv and --figure both"),
    ({"--csv": "{tmp}/x.png", "--figure": "{tmp}/link.png"}, "--csv and --figure both write"),
    ({"--report": "{tmp}/sub"}, "it is a directory"),
    ({"--report": "{tmp}/missing/r.json"}, "directory {tmp}/missing does not exist"),
    ({"--report": "{tmp}/file/r.json"}, "directory {tmp}/file is not a directory"),
])
def test_check_outputs_refuses(outputs, message, tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "file").write_text("")
    (tmp_path / "link.png").symlink_to(tmp_path / "x.png")
    before = sorted(os.listdir(tmp_path))
    with pytest.raises((OSError, ValueError), match=message.replace("{tmp}", str(tmp_path))):
        check_outputs({k: v.replace("{tmp}", str(tmp_path)) for k, v in outputs.items()})
    assert sorted(os.listdir(tmp_path)) == before


def test_sigterm_inside_atomic_path_removes_the_temporary_file(tmp_path):
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Terminated):
        with atomic_path(tmp_path / "v.mp4") as tmp:
            tmp.write_bytes(b"partial")
            os.kill(os.getpid(), signal.SIGTERM)
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is before           # handler restored
    with atomic_path(tmp_path / "v.mp4") as tmp:                # and writing still works
        tmp.write_bytes(b"whole")
    assert (tmp_path / "v.mp4").read_bytes() == b"whole"


def test_sigterm_handler_only_in_the_main_thread():
    seen = []

    def work():
        with sigterm_raises():
            seen.append(signal.getsignal(signal.SIGTERM))

    before = signal.getsignal(signal.SIGTERM)
    t = threading.Thread(target=work)
    t.start()
    t.join()
    assert seen == [before]


def test_outputs_never_resolve_into_the_shipped_files(tmp_path):
    """An output in policies/ or models/, directly or through a symlinked folder, is
    refused before any work; --ship alone writes there."""
    import subprocess
    import sys

    from twolink.policy.registry import SHIPPED
    from twolink.resources import model_file, shipped_policy_dir

    link = tmp_path / "dir"
    link.symlink_to(shipped_policy_dir(), target_is_directory=True)
    shipped = SHIPPED["centralized"].file
    before = shipped.read_bytes()
    for argv in (["synthesize", "centralized", "-o", str(link / "centralized.npz"), "--force"],
                 ["mjcf", "-o", str(model_file())]):
        res = subprocess.run([sys.executable, "-m", "twolink.cli", *argv], capture_output=True,
                             text=True, timeout=120)
        assert res.returncode == 2, res.stderr
        assert "resolves into twolink's shipped files" in res.stderr
        assert res.stderr.count("\n") == 1
    assert shipped.read_bytes() == before


def test_an_output_written_with_a_trailing_slash_is_a_folder_made_for_it(tmp_path, capsys):
    from twolink.cli import main

    folder = tmp_path / "new"
    assert main(["mjcf", "-o", f"{folder}/"]) == 0, capsys.readouterr().err
    assert [p.name for p in folder.iterdir()] == ["twolink.xml"]
    deeper = tmp_path / "missing" / "new"
    assert main(["mjcf", "-o", f"{deeper}/"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "directory" in err and "does not exist" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new"]


class _Stop(Exception):
    """Raised by a stub where the real work would start."""


def test_identify_takes_a_folder_with_a_trailing_slash(tmp_path, capsys, monkeypatch):
    """The folder passes the checks and is made only when the file is written (the work
    is stubbed: only where the command writes is at stake)."""
    from twolink.cli import main
    from twolink.commands import identify

    monkeypatch.setattr(identify.excitation, "experiment",
                        lambda *a, **k: (_ for _ in ()).throw(_Stop()))
    with pytest.raises(_Stop):
        main(["identify", "-o", f"{tmp_path / 'i'}/"])
    assert not (tmp_path / "i").exists()                   # nothing before the work
    assert main(["identify", "-o", f"{tmp_path / 'no' / 'i'}/"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_synthesize_takes_a_folder_with_a_trailing_slash(tmp_path, monkeypatch):
    from twolink.cli import main
    from twolink.commands import synthesize
    from twolink.policy.fuzzy_policy import load_policy

    monkeypatch.setattr(synthesize, "synthesize",
                        lambda kind, **k: load_policy("decentralized"))
    assert main(["synthesize", "decentralized", "--json", "-o", f"{tmp_path / 's'}/"]) == 0
    assert [p.name for p in (tmp_path / "s").iterdir()] == ["decentralized.npz"]


def test_learn_takes_a_folder_with_a_trailing_slash(tmp_path, monkeypatch):
    from twolink.cli import main
    from twolink.commands import learn

    seen = []

    class Learner:
        def __init__(self, config, init=None, nthread=1):
            pass

        def run(self, *, checkpoint, progress):
            seen.append(checkpoint)
            raise _Stop

        def close(self):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.close()

    monkeypatch.setattr(learn, "Learner", Learner)
    with pytest.raises(_Stop):
        main(["learn", "--task", "decentralized", "-o", f"{tmp_path / 'l'}/"])
    assert seen == [tmp_path / "l" / "learned_decentralized.npz"]
    assert (tmp_path / "l").is_dir()


def test_read_runs_merges_only_files_of_its_own_schema(tmp_path):
    import json

    import pytest

    from twolink.artifacts import read_runs
    assert read_runs(tmp_path / "none.json", "twolink.x", 1) == {"runs": []}
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"schema": "twolink.x", "version": 1, "runs": [{"seed": 3}]}))
    assert read_runs(good, "twolink.x", 1)["runs"] == [{"seed": 3}]
    with pytest.raises(ValueError, match=r"good.json is not a twolink.x version 2 file; "
                                         r"give another --json PATH"):
        read_runs(good, "twolink.x", 2)
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(ValueError, match=r"broken.json: not valid JSON"):
        read_runs(broken, "twolink.x", 1)


def _merge_many(path: str, start: int, count: int, go) -> None:
    from twolink.artifacts import merge_run

    go.wait(30)                                             # both processes start together
    for i in range(start, start + count):
        merge_run(path, "twolink.x", 1, {"id": f"run{i:03d}", "n": i}, note=f"by {start}")


def test_merge_run_keeps_the_runs_of_processes_writing_the_same_file(tmp_path):
    import json
    import multiprocessing

    from twolink.artifacts import merge_run

    path = tmp_path / "study.json"
    merge_run(path, "twolink.x", 1, {"id": "b", "n": 1})
    data = merge_run(path, "twolink.x", 1, {"id": "a", "n": 2}, poses=8)
    assert [r["id"] for r in data["runs"]] == ["a", "b"] and data["poses"] == 8
    # a record of the same id replaces the old one
    merge_run(path, "twolink.x", 1, {"id": "b", "n": 3})
    assert json.loads(path.read_text())["runs"] == [{"id": "a", "n": 2}, {"id": "b", "n": 3}]
    # two processes, 60 runs each, read-change-write the same file at once: none is lost
    ctx = multiprocessing.get_context("spawn")
    go = ctx.Event()
    procs = [ctx.Process(target=_merge_many, args=(str(path), s, 60, go)) for s in (0, 100)]
    for p in procs:
        p.start()
    time.sleep(1.0)                                         # both imported, waiting
    go.set()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0]
    ids = [r["id"] for r in json.loads(path.read_text())["runs"]]
    assert len(ids) == 122 and {f"run{i:03d}" for i in [*range(60), *range(100, 160)]} <= set(ids)
    assert ids == sorted(ids)
    with pytest.raises(ValueError, match="is not a twolink.x version 2 file"):
        merge_run(path, "twolink.x", 2, {"id": "c"})


class _SignalWhileConverting:
    """A ctypes argument type whose conversion receives ``signum``: the handler's
    exception is raised inside ctypes, which wraps it in ``ctypes.ArgumentError`` (as
    happens in PyOpenGL's EGL calls when a render is terminated)."""

    signum = signal.SIGTERM

    @classmethod
    def from_param(cls, value):
        os.kill(os.getpid(), cls.signum)
        return ctypes.c_int(value)


@pytest.mark.parametrize("signum, code, line", [(signal.SIGTERM, 143, "twolink: terminated"),
                                                (signal.SIGINT, 130, "twolink: interrupted")])
def test_a_signal_wrapped_by_a_foreign_call_is_reported_as_the_signal(
        monkeypatch, capsys, signum, code, line):
    from twolink import cli

    libc_abs = ctypes.CDLL(None).abs
    libc_abs.argtypes = [_SignalWhileConverting]
    monkeypatch.setattr(_SignalWhileConverting, "signum", signum)
    def run(args):
        with pytest.raises(ctypes.ArgumentError, match="argument 1"):
            libc_abs(-3)                   # the wrapped exception, as the command sees it
        libc_abs(-3)

    monkeypatch.setattr("twolink.commands.limits.run", run)
    # a shell's background job starts with SIGINT ignored, and the CLI keeps an ignored
    # signal ignored: give this process Python's own SIGINT handler while the test runs
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        before = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
        assert cli.main(["limits"]) == code
        assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)) == before
    finally:
        signal.signal(signal.SIGINT, inherited)
    assert capsys.readouterr().err.strip() == line


def test_an_unexpected_exception_without_a_signal_is_not_hidden(monkeypatch):
    from twolink import cli

    def run(args):
        raise TypeError("a bug")

    monkeypatch.setattr("twolink.commands.limits.run", run)
    with pytest.raises(TypeError, match="a bug"):
        cli.main(["limits"])
