"""simgap.fleet on a real Dask cluster: a scheduler and two worker processes started here on the
loopback address diagnose a synthetic fleet of the paper's arm (6 robots × 5 days: one robot's
elbow Coulomb friction rising 10 % a day, one carrying a payload from day 3, the rest nominal
with a 3 % spread). Exactly the rising robot drifts and exactly the payload robot stands out,
from day 3; killing a worker mid-run loses no result; a broken robot-day is recorded with its
error while the rest go on; the command line and its Ctrl-C; the LocalCluster example."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pd = pytest.importorskip("pandas")
distributed = pytest.importorskip("distributed")

from simgap import fleet  # noqa: E402
from simgap.fleet.synthetic import SyntheticFleet, make_synthetic_fleet  # noqa: E402

START_TIMEOUT_S = 60
RESULT_TIMEOUT_S = 120


def spawn(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    """A process of this Python in its own session, output to ``log``, one core's worth of threads."""
    env = {**os.environ, "RAYON_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    with open(log, "wb") as out:
        return subprocess.Popen([sys.executable, *args], stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env, start_new_session=True)


def stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


class Cluster:
    """A scheduler and named worker processes on 127.0.0.1."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.scheduler_file = folder / "scheduler.json"
        self.procs: list[subprocess.Popen[bytes]] = []
        self.workers: dict[str, subprocess.Popen[bytes]] = {}
        self.procs.append(spawn(["-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--scheduler-file", str(self.scheduler_file)], folder / "scheduler.log"))
        deadline = time.monotonic() + START_TIMEOUT_S
        while True:  # the scheduler file, once written whole
            try:
                self.address = json.loads(self.scheduler_file.read_text())["address"]
                break
            except (OSError, ValueError, KeyError):
                if time.monotonic() > deadline or self.procs[0].poll() is not None:
                    self.close()
                    raise RuntimeError(f"the scheduler did not start: {(folder / 'scheduler.log').read_text()}") from None
                time.sleep(0.2)

    def start_worker(self, name: str) -> None:
        args = ["-m", "distributed.cli.dask_worker", "--scheduler-file", str(self.scheduler_file), "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny", "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--name", name, "--death-timeout", "60"]
        proc = spawn(args, self.folder / f"{name}.log")
        self.procs.append(proc)
        self.workers[name] = proc

    def kill_worker(self, name: str) -> None:
        """SIGKILL, as a machine that dies: no goodbye to the scheduler."""
        self.workers[name].kill()
        self.workers[name].wait(10)

    def close(self) -> None:
        for proc in reversed(self.procs):
            stop(proc)


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> SyntheticFleet:
    return make_synthetic_fleet(tmp_path_factory.mktemp("fleet"))


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Cluster, Any]]:
    c = Cluster(tmp_path_factory.mktemp("dask"))  # stops its scheduler itself if it fails to start
    client = None
    try:
        assert c.address.startswith("tcp://127.0.0.1:"), c.address
        c.start_worker("w1")
        c.start_worker("w2")
        client = distributed.Client(c.address, timeout=f"{START_TIMEOUT_S}s")
        client.wait_for_workers(2, timeout=START_TIMEOUT_S)
        yield c, client
    finally:
        if client is not None:
            client.close()
        c.close()


@pytest.fixture(scope="module")
def fleet_run(synthetic: SyntheticFleet, cluster: tuple[Cluster, Any], tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict[str, Any]], str, float]:
    """The synthetic fleet plus one broken robot-day, streamed from the cluster; worker w2 is
    killed once half of the results are in. Returns the results, the killed worker's process
    id and when it was killed."""
    c, client = cluster
    broken = tmp_path_factory.mktemp("broken")
    (broken / "a.mcap").write_text("not an mcap file")
    (broken / "b.mcap").write_text("not an mcap file either")
    index = pd.concat([fleet.index_from_folder(synthetic.root), fleet.index_from_table([{"robot": "arm-99", "day": synthetic.days[0], "path": str(broken / n)} for n in ("a.mcap", "b.mcap")])])
    killed_pid = c.workers["w2"].pid
    results = []
    killed_at = math.nan
    for result in fleet.iter_fleet(index, synthetic.urdf, client, timeout=RESULT_TIMEOUT_S):
        results.append(result)
        if len(results) == len(index) // 4:  # about half of the robot-days (2 logs each)
            killed_at = time.time()
            c.kill_worker("w2")
    return results, str(killed_pid), killed_at


def test_killing_a_worker_mid_run_loses_no_result(synthetic: SyntheticFleet, fleet_run: tuple[list[dict[str, Any]], str, float], cluster: tuple[Cluster, Any]) -> None:
    results, killed_pid, killed_at = fleet_run
    c, client = cluster
    assert c.workers["w2"].poll() is not None, "w2 was killed"
    days = {(r["robot"], r["day"]) for r in results}
    assert len(results) == len(days) == len(synthetic.robots) * len(synthetic.days) + 1
    ok = [r for r in results if r["robot"] != "arm-99"]
    assert all(r["status"] == "ok" for r in ok), [r["error"] for r in ok if r["status"] != "ok"]
    workers = {r["worker"].rsplit(":", 1)[1] for r in ok}
    assert killed_pid in workers, "the killed worker had diagnosed some robot-days before it died"
    assert len(workers) == 2
    late = [r for r in ok if r["finished_at"] > killed_at]
    assert len(late) >= 10, "about half of the robot-days were diagnosed after the kill"
    assert all(r["worker"].rsplit(":", 1)[1] != killed_pid for r in late), "after the kill, the surviving worker did the rest"


def test_a_broken_robot_day_is_recorded_with_its_error(fleet_run: tuple[list[dict[str, Any]], str, float]) -> None:
    results = fleet_run[0]
    (broken,) = [r for r in results if r["robot"] == "arm-99"]
    assert broken["status"] == "error" and broken["error"].startswith("LogError") and broken["report"] is None
    result = fleet.FleetResult.from_results(results)
    assert list(result.failed["robot"]) == ["arm-99"]
    row = result.table[result.table["robot"] == "arm-99"]
    assert len(row) == 1 and row["status"].iloc[0] == "error" and "LogError" in row["error"].iloc[0]


def test_exactly_the_rising_robot_drifts_and_the_payload_robot_stands_out_from_day_3(synthetic: SyntheticFleet, fleet_run: tuple[list[dict[str, Any]], str, float], tmp_path: Path) -> None:
    result = fleet.FleetResult.from_results(fleet_run[0])
    found = fleet.find(result.table, result.reports)
    dr, ol = found.drift, found.outliers
    drifting = dr[dr["drifting"]]
    assert set(drifting["robot"]) == {synthetic.rising}, drifting
    assert set(zip(drifting["effect"], drifting["joint"], drifting["parameter"], drifting["change"])) == {("coulomb_friction", "elbow", "fc", "trend")}
    rate = drifting["rate_per_day"].iloc[0]
    assert 0.07 < rate < 0.13, "10 % of day 1's value a day"
    flagged = ol[ol["outlier"]]
    assert set(flagged["robot"]) == {synthetic.payload}, flagged
    assert min(flagged["day"]) == synthetic.payload_from
    payload = flagged[flagged["effect"] == "payload"]
    assert set(payload["day"]) == {d for d in synthetic.days if d >= synthetic.payload_from} and set(payload["reference"]) == {"neutral"}
    mass = result.table[(result.table["effect"] == "payload") & (result.table["parameter"] == "mass")]
    assert set(mass["robot"]) == {synthetic.payload} and mass["value"].between(1.35, 1.65).all()
    flags = found.flags
    assert list(zip(flags["robot"], flags["finding"], flags["since"])) == [(synthetic.rising, "drift", synthetic.days[0]), (synthetic.payload, "effect", synthetic.payload_from)]
    # the table holds every robot-day's figures, and goes to Parquet
    table = result.table
    assert (table.loc[table["status"] == "ok", "l2_after"] < table.loc[table["status"] == "ok", "l2_before"]).all()
    result.to_parquet(tmp_path / "fleet.parquet")
    back = pd.read_parquet(tmp_path / "fleet.parquet")
    assert list(back.columns) == fleet.TABLE_COLUMNS and len(back) == len(table)
    # the HTML report: each finding day by day, then one plot per parameter, flagged robots named
    result.to_html(tmp_path / "fleet.html")
    text = (tmp_path / "fleet.html").read_text()
    per_parameter = ol[ol["reference"] == "fleet"].groupby(["effect", "joint", "parameter"]).ngroups + 1  # frictions ×4, payload mass
    assert per_parameter == 5
    assert text.startswith("<!DOCTYPE html>") and text.count("<svg") == len(flags) + per_parameter
    assert f"{synthetic.rising}</b> (drift)" in text and f"{synthetic.payload}</b> (effect)" in text


def small_fleet(synthetic: SyntheticFleet, folder: Path) -> Path:
    """Two nominal robots on two days of the synthetic fleet, as links."""
    for robot in synthetic.robots[2:4]:
        for day in synthetic.days[:2]:
            (folder / robot).mkdir(parents=True, exist_ok=True)
            (folder / robot / day).symlink_to(synthetic.root / robot / day)
    return folder


def test_command_line_writes_every_output(synthetic: SyntheticFleet, cluster: tuple[Cluster, Any], tmp_path: Path) -> None:
    c, _ = cluster
    folder = small_fleet(synthetic, tmp_path / "fleet")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "simgap.fleet", str(folder), "--urdf", str(synthetic.urdf), "--scheduler", c.address, "--out", str(out)], capture_output=True, text=True, timeout=RESULT_TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr
    assert "4 of 4 robot-days diagnosed" in proc.stdout and "no robot changes or stands out" in proc.stdout
    assert "4/4" in proc.stderr, "a progress bar over the tasks"
    assert sorted(p.name for p in out.iterdir()) == ["drift.csv", "flagged.csv", "fleet.html", "fleet.parquet", "outliers.csv", "reports", "tasks.csv"]
    assert len(list((out / "reports").glob("*/*.json"))) == 4
    again = fleet.FleetResult.read(out)
    assert len(again.tasks) == 4 and set(again.tasks["status"]) == {"ok"} and len(again.reports) == 4
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.partial")]


@pytest.mark.parametrize("where", ["scheduler", "local_cluster"])
def test_command_line_ctrl_c_exits_130_and_writes_nothing(where: str, synthetic: SyntheticFleet, cluster: tuple[Cluster, Any], tmp_path: Path) -> None:
    """Ctrl-C as a terminal sends it: SIGINT to the whole process group (with a LocalCluster,
    its worker processes too)."""
    c, _ = cluster
    folder = small_fleet(synthetic, tmp_path / "fleet")
    out = tmp_path / "out"
    log = tmp_path / "cli.log"
    target = ["--scheduler", c.address] if where == "scheduler" else ["--workers", "1"]
    with open(log, "wb") as f:
        proc = subprocess.Popen([sys.executable, "-m", "simgap.fleet", str(folder), "--urdf", str(synthetic.urdf), *target, "--out", str(out)], stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while "fleet:" not in log.read_text(errors="replace"):  # the progress bar: tasks submitted
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.1)
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(60) == 130, log.read_text()
    finally:
        stop(proc)
        try:  # whatever is left of the group this test started (its LocalCluster's workers)
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".out.partial")]
    text = log.read_text()
    assert "interrupted" in text and "Traceback" not in text, text


def test_a_task_that_raises_is_retried_then_recorded(synthetic: SyntheticFleet, cluster: tuple[Cluster, Any]) -> None:
    _, client = cluster
    index = fleet.index_from_folder(synthetic.root)
    one_day = index[(index["robot"] == synthetic.robots[3]) & (index["day"] == synthetic.days[0])]
    # an option read_log does not take: a TypeError on the worker, not a data error
    (result,) = fleet.iter_fleet(one_day, synthetic.urdf, client, retries=1, read_options={"no_such_option": 1}, timeout=RESULT_TIMEOUT_S)
    assert result["status"] == "error" and result["error"].startswith("TypeError") and "no_such_option" in result["error"]
