"""``pyorch sweep --cluster slurm`` end to end on a real (single-node) Slurm.

scripts/slurm_local.sh installs (apt-get, as root) and starts munge + slurmctld +
slurmd; the sweep is examples/slurm/sweep.toml (4 points of 1000 oscillators,
~2.5 s each) with the dask-jobqueue settings of examples/slurm/jobqueue.yaml,
run through the ``pyorch`` command exactly as the README's cluster section says:

0. with one worker whose job waits in the queue (a job holding the node), that job is
   cancelled: pyorch sweep submits another (dask-jobqueue never notices);
1. then, its job is killed by ``scancel`` while a point runs: the engine
   checkpoints on Slurm's SIGTERM, pyorch sweep submits a new job (without that the
   sweep would wait forever), the point is resumed in the same sweep and its output is
   byte-identical to an uninterrupted run;
2. the sweep is run again: every point is skipped, no engine runs;
3. a fresh sweep whose running job is cancelled and whose client is stopped
   (SIGTERM): the client cancels its jobs and exits with 130 like on Ctrl-C; the next
   run of the sweep resumes the killed point from its checkpoint, byte-identical again.

The final energies are checked against the exact decay of a lightly damped
oscillator, E(t)/E(0) = exp(-2 zeta omega t) to O(zeta) (zeta = 1e-4, 3e-4: within 5 zeta).

Skipped only where Slurm is absent and cannot be installed (not root, or no
apt-get); on CI (root, Debian) it runs. Every wait has a timeout with a message;
the sweep's jobs are cancelled whatever happens.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pyorch import run as prun
from pyorch.scene import Scene
from pyorch.sweep import Sweep, read_results

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "slurm"
SCRIPT = ROOT / "scripts" / "slurm_local.sh"
# examples/slurm/jobqueue.yaml names the jobs pyorch-sweep; this test's own name keeps its
# clean-up (scancel --name) away from the jobs of anyone else's sweep on the same Slurm
JOB_NAME = f"pyorch-sweep-test{os.getpid()}"
BLOCKER = f"{JOB_NAME}-blocker"
PYORCH = Path(sys.executable).parent / "pyorch"
SWEEP_TIMEOUT_S = 120.0            # one sweep of 4 points on 2 one-core jobs takes ~15 s


SLURM_CONF = Path("/etc/slurm/slurm.conf")
CONF_MARK = "# written by pyorch scripts/slurm_local.sh"  # its first line (scripts/slurm_local.sh)


def foreign_slurm_conf(conf: Path = SLURM_CONF) -> str | None:
    """Why this test cannot run when ``conf`` belongs to another Slurm (it exists and was not
    written by scripts/slurm_local.sh, which refuses to replace it); None otherwise."""
    try:
        with open(conf, encoding="utf-8", errors="replace") as fh:
            first = fh.readline()
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"{conf} cannot be read ({exc.strerror}): not the configuration of scripts/slurm_local.sh"
    if first.startswith(CONF_MARK):
        return None
    return (f"{conf} belongs to another Slurm (not written by scripts/slurm_local.sh, which "
            f"refuses to replace a real cluster's configuration): this test runs only on the "
            f"single-node Slurm of that script")


def _have_slurm() -> bool:
    return all(shutil.which(c) for c in ("slurmctld", "slurmd", "sbatch", "munged"))


def _can_install() -> bool:
    return os.geteuid() == 0 and shutil.which("apt-get") is not None


def _squeue_ids(states: str | None = None) -> list[int]:
    """Job ids of this test's sweeps in the queue (pending, running, completing, or ``states``)."""
    cmd = ["squeue", "-h", "--name", JOB_NAME, "-o", "%i"] + (["-t", states] if states else [])
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=20, check=True).stdout
    return sorted(int(x) for x in out.split())


def _cancel_ours() -> None:
    for name in (JOB_NAME, BLOCKER):
        subprocess.run(["scancel", "--name", name], capture_output=True, timeout=20)


def _block_the_node() -> str:
    """A job holding every CPU of the node, so the sweep's first job waits in the queue."""
    cpus = subprocess.run(["sinfo", "-h", "-o", "%c"], capture_output=True, text=True,
                          timeout=20, check=True).stdout.split()[0]
    return subprocess.run(["sbatch", "--parsable", "-J", BLOCKER, "-c", cpus, "-o", "/dev/null",
                           "--wrap", "sleep 300"], capture_output=True, text=True, timeout=20,
                          check=True).stdout.strip().split(";")[0]


def _cancel_pending_job(spec: Path) -> None:
    """scancel the sweep's job while it is pending; wait for pyorch sweep to submit another."""
    deadline = time.monotonic() + 60.0
    first = []
    while not first and time.monotonic() < deadline:
        first = _squeue_ids("PENDING")
        time.sleep(0.2)
    assert len(first) == 1, f"no pending job of the sweep within 60 s\n{_diagnostics(spec)}"
    subprocess.run(["scancel", str(first[0])], check=True, timeout=20)
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        if any(j > first[0] for j in _squeue_ids()):
            return
        time.sleep(0.2)
    pytest.fail(f"job {first[0]}, cancelled while pending, was not re-submitted within 30 s\n"
                f"{_diagnostics(spec)}")


@pytest.fixture(scope="module")
def slurm():
    """A running single-node Slurm (started by scripts/slurm_local.sh, stopped again if it
    was not running before); the sweep's jobs are cancelled at the end."""
    foreign = foreign_slurm_conf()
    if foreign:
        pytest.skip(foreign)
    was_up = _have_slurm() and subprocess.run(["bash", str(SCRIPT), "status"],
                                              capture_output=True, timeout=30).returncode == 0
    if not was_up and not _can_install():
        pytest.skip("no local Slurm running and none can be started here: scripts/slurm_local.sh "
                    "needs root and apt-get (Debian/Ubuntu)")
    try:
        res = subprocess.run(["bash", str(SCRIPT)], capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        pytest.fail("scripts/slurm_local.sh did not finish in 600 s (apt-get or daemons hanging)")
    assert res.returncode == 0, f"scripts/slurm_local.sh failed:\n{res.stdout}\n{res.stderr}"
    _cancel_ours()
    yield
    _cancel_ours()
    if not was_up:
        subprocess.run(["bash", str(SCRIPT), "stop"], capture_output=True, timeout=60)


def _example_copy(where: Path) -> Path:
    """examples/slurm's spec and scene in ``where`` (so its sweep directory is where/out)."""
    where.mkdir(parents=True)
    for f in ("sweep.toml", "oscillator.nml"):
        shutil.copy(EXAMPLE / f, where / f)
    return where / "sweep.toml"


def _start(spec: Path, workers: int) -> subprocess.Popen:
    """``DASK_CONFIG=examples/slurm pyorch sweep SPEC --cluster slurm --workers N --no-progress``."""
    env = {**os.environ, "DASK_CONFIG": str(EXAMPLE), "DASK_JOBQUEUE__SLURM__NAME": JOB_NAME,
           "PYTHONUNBUFFERED": "1"}
    with open(spec.parent / "client.log", "a") as log:
        return subprocess.Popen([str(PYORCH), "sweep", str(spec), "--cluster", "slurm",
                                 "--workers", str(workers), "--no-progress"],
                                cwd=spec.parent, env=env, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)


def _diagnostics(spec: Path) -> str:
    """Client log, the workers' Slurm logs and the queue (for failure messages)."""
    parts = [f"--- client.log\n{(spec.parent / 'client.log').read_text(errors='replace')[-4000:]}"]
    for f in sorted((spec.parent / "dask-logs").glob("*.err"))[-4:]:
        parts.append(f"--- {f.name}\n{f.read_text(errors='replace')[-1500:]}")
    q = subprocess.run(["squeue"], capture_output=True, text=True, timeout=20).stdout
    return "\n".join(parts + [f"--- squeue\n{q}"])


def _wait(proc: subprocess.Popen, spec: Path, what: str) -> int:
    try:
        return proc.wait(timeout=SWEEP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        pytest.fail(f"{what}: pyorch sweep did not end in {SWEEP_TIMEOUT_S:.0f} s\n"
                    f"{_diagnostics(spec)}")


def _status(point: Path) -> dict:
    try:
        return json.loads((point / "run.json").read_text())
    except (OSError, ValueError):
        return {}


def _engine_job(point: Path) -> int | None:
    """Slurm job id of the engine writing into ``point`` (its SLURM_JOB_ID), if one runs."""
    import psutil

    for proc in psutil.process_iter(["cmdline"]):
        cmd = proc.info.get("cmdline") or []
        if cmd and Path(cmd[0]).name == "partsim" and str(point) in cmd:
            try:
                return int(proc.environ()["SLURM_JOB_ID"])
            except (psutil.Error, KeyError, ValueError):
                return None
    return None


def _kill_a_running_point(spec: Path, proc: subprocess.Popen) -> tuple[Path, int]:
    """Wait for a point past its first periodic checkpoint, scancel the job running it;
    returns the point and the job id once the engine has written 'interrupted'."""
    out = spec.parent / "out"
    deadline = time.monotonic() + 90.0
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"the sweep ended before a point could be killed\n{_diagnostics(spec)}"
        for point in sorted(p for p in out.glob("*-*") if p.is_dir()):
            st = _status(point)
            if st.get("status") == "running" and 100_000 <= st.get("steps_done", 0) <= 600_000:
                job = _engine_job(point)
                if job is not None:
                    subprocess.run(["scancel", str(job)], check=True, timeout=20)
                    t0 = time.monotonic()
                    while time.monotonic() - t0 < 30.0:
                        if str(_status(point).get("status", "")).startswith("interrupted"):
                            assert (point / "checkpoint.bin").is_file()
                            return point, job
                        time.sleep(0.1)
                    pytest.fail(f"{point.name}: job {job} cancelled but run.json is "
                                f"{_status(point).get('status')!r} after 30 s")
        time.sleep(0.1)
    pytest.fail(f"no point of {out} was seen running within 90 s\n{_diagnostics(spec)}")


def _reference(spec: Path, point: Path, where: Path) -> bytes:
    """energy.dat of the same point run here without interruption (the exe door)."""
    row = Sweep.from_toml(spec).points().set_index("name").loc[point.name]
    ref = prun.run(spec.parent / "oscillator.nml", where, overrides=row["overrides"],
                   door="exe", progress=False, threads=1)
    return (ref.dir / "energy.dat").read_bytes()


def _check_physics(df: pd.DataFrame) -> None:
    """E(T)/E(0) = exp(-2 zeta omega T) to O(zeta) for lightly damped oscillators."""
    scene = Scene.read(EXAMPLE / "oscillator.nml")
    omega, t_end = scene.get("oscillator", "omega"), scene.get("oscillator", "t_end")
    for name, zeta, rel_change in zip(df["name"], df["oscillator.zeta"], df["E_rel_change"]):
        expected = math.exp(-2.0 * zeta * omega * t_end)
        assert 1.0 + rel_change == pytest.approx(expected, rel=5 * zeta), name


def test_sweep_on_slurm_survives_scancel_and_resumes(slurm, tmp_path):
    t_start = time.monotonic()
    # 1. the only job cancelled mid-point: a new job is submitted, the point resumes in this run
    spec = _example_copy(tmp_path / "a")
    blocker = _block_the_node()
    proc = _start(spec, workers=1)
    try:
        _cancel_pending_job(spec)  # 0. cancelled while still pending: submitted again
        subprocess.run(["scancel", blocker], check=True, timeout=20)
        point, job = _kill_a_running_point(spec, proc)
        rc = _wait(proc, spec, "run 1 (one job cancelled)")
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        _cancel_ours()
    assert rc == 0, _diagnostics(spec)
    df = read_results(spec.parent / "out" / "results.csv")
    assert (df["status"] == "completed").all(), df.to_string()
    actions = dict(zip(df["name"], df["action"]))
    assert actions.pop(point.name) == "resumed", df.to_string()
    assert set(actions.values()) == {"ran"}, df.to_string()
    jobs = sorted(int(f.stem.rsplit("-", 1)[1]) for f in (spec.parent / "dask-logs").glob("*.err"))
    assert len(jobs) >= 2 and jobs[0] == job and jobs[-1] > job, \
        f"expected job {job} and one submitted after it was cancelled, got {jobs}"
    assert (point / "energy.dat").read_bytes() == _reference(spec, point, tmp_path / "ref_a")
    _check_physics(df)
    t_run1 = time.monotonic() - t_start

    # 2. the same sweep again: nothing runs
    mtimes = {p.name: (p / "energy.dat").stat().st_mtime_ns for p in (spec.parent / "out").glob("*-*")}
    proc = _start(spec, workers=2)
    try:
        assert _wait(proc, spec, "run 2 (all done)") == 0, _diagnostics(spec)
    finally:
        _cancel_ours()
    df2 = read_results(spec.parent / "out" / "results.csv")
    assert (df2["action"] == "skipped").all(), df2.to_string()
    assert mtimes == {p.name: (p / "energy.dat").stat().st_mtime_ns
                      for p in (spec.parent / "out").glob("*-*")}
    pd.testing.assert_series_equal(df2["E_final"], df["E_final"])

    # 3. a job cancelled and the client stopped: the next run resumes the point
    spec = _example_copy(tmp_path / "b")
    proc = _start(spec, workers=2)
    try:
        point, job = _kill_a_running_point(spec, proc)
        os.kill(proc.pid, signal.SIGTERM)
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"pyorch sweep did not stop within 60 s of SIGTERM\n{_diagnostics(spec)}")
        # SIGTERM stops pyorch sweep like Ctrl-C (130, "pyorch: interrupted"), closing its
        # cluster: its jobs are cancelled now rather than when the workers notice the lost
        # scheduler (a pending job would only notice after starting and its death-timeout)
        assert rc == 130, f"pyorch sweep exited {rc} on SIGTERM\n{_diagnostics(spec)}"
        deadline = time.monotonic() + 30.0
        while _squeue_ids() and time.monotonic() < deadline:
            time.sleep(0.5)
        assert not _squeue_ids(), f"jobs left after the client stopped\n{_diagnostics(spec)}"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        _cancel_ours()
    assert str(_status(point)["status"]).startswith("interrupted")
    proc = _start(spec, workers=2)
    try:
        rc = _wait(proc, spec, "run 4 (resume after the stop)")
    finally:
        _cancel_ours()
    assert rc == 0, _diagnostics(spec)
    df = read_results(spec.parent / "out" / "results.csv")
    assert (df["status"] == "completed").all(), df.to_string()
    assert dict(zip(df["name"], df["action"]))[point.name] == "resumed", df.to_string()
    assert (point / "energy.dat").read_bytes() == _reference(spec, point, tmp_path / "ref_b")
    _check_physics(df)
    print(f"\nslurm sweep: run 1 (scancel, re-submit, resume) {t_run1:.1f} s, "
          f"all {time.monotonic() - t_start:.1f} s")


def test_foreign_slurm_conf_is_a_reason_to_skip(tmp_path: Path) -> None:
    """A /etc/slurm/slurm.conf of another Slurm made the module fixture error (the script
    refuses to replace it): it is now a skip with that reason; the script's own, or none, is
    no reason."""
    conf = tmp_path / "slurm.conf"
    assert foreign_slurm_conf(conf) is None
    conf.write_text(f"{CONF_MARK} (single node; 2026-01-01T00:00:00Z)\nClusterName=pyorch-local\n")
    assert foreign_slurm_conf(conf) is None
    conf.write_text("ClusterName=hpc\nSlurmctldHost=head01\n")
    reason = foreign_slurm_conf(conf)
    assert reason is not None and reason.startswith(f"{conf} belongs to another Slurm")
    script_mark = next(line for line in SCRIPT.read_text().splitlines() if line.startswith("MARK="))
    assert script_mark == f'MARK="{CONF_MARK}"'  # the same mark as the script's
