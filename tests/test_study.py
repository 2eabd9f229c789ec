"""Studies: spec expansion, the runner's mechanics (resume after kill -9, failing runs,
Dask), bad input. The runner is exercised with the hidden ``_test`` kind (y = x**2);
tests/test_study_e2e.py runs a real (tiny) peak-detector study."""

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pandas as pd
import pytest

from scanamp.cli import main
from scanamp.study import is_suite, load_study, load_suite, run_study, shipped_studies

ROOT = Path(__file__).resolve().parents[1]


def _spec(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


GRID = """
[study]
name = "t"
kind = "_test"
seed = 3
[base]
sleep = 0.0
[sweep]
x = [1, 2, 3]
"reconstruct.scale" = [1.0, 10.0]
[output]
metrics = ["y", "x"]
"""


def test_grid_is_the_cartesian_product_with_base_applied(tmp_path):
    st = load_study(_spec(tmp_path, GRID))
    assert len(st.runs) == 6
    assert [(r.params["x"], r.params["reconstruct.scale"]) for r in st.runs] == [
        (1, 1.0), (1, 10.0), (2, 1.0), (2, 10.0), (3, 1.0), (3, 10.0)]
    assert all(r.overrides["sleep"] == 0.0 and r.seed == 3 for r in st.runs)
    assert len({r.run_id for r in st.runs}) == 6
    # ids depend on the values only: the same spec in another file gives the same ids
    again = load_study(_spec(tmp_path, GRID, "other.toml"))
    assert [r.run_id for r in again.runs] == [r.run_id for r in st.runs]
    # ... and change when [base] changes (a resumed study never mixes configurations)
    changed = load_study(_spec(tmp_path, GRID.replace("sleep = 0.0", "sleep = 0.001"), "c.toml"))
    assert not {r.run_id for r in changed.runs} & {r.run_id for r in st.runs}


RANDOM = """
[study]
kind = "_test"
seed = {seed}
mode = "random"
n = 12
[sweep]
x = {{min = 0.5, max = 4.0}}
sleep = {{min = 0.001, max = 0.01, log = true}}
"reconstruct.scale" = {{choices = [1.0, 2.0, 5.0]}}
"""


def test_random_sweep_is_seeded_and_within_bounds(tmp_path):
    a = load_study(_spec(tmp_path, RANDOM.format(seed=7), "a.toml"))
    b = load_study(_spec(tmp_path, RANDOM.format(seed=7), "b.toml"))
    c = load_study(_spec(tmp_path, RANDOM.format(seed=8), "c.toml"))
    assert [r.params for r in a.runs] == [r.params for r in b.runs]
    assert [r.run_id for r in a.runs] == [r.run_id for r in b.runs]
    assert [r.params for r in a.runs] != [r.params for r in c.runs]
    assert len(a.runs) == 12
    for r in a.runs:
        assert 0.5 <= r.params["x"] <= 4.0 and 0.001 <= r.params["sleep"] <= 0.01
        assert r.params["reconstruct.scale"] in (1.0, 2.0, 5.0)


def test_shipped_studies_load_by_name_and_validate():
    assert {"laser-angle", "stereo-baseline", "sfm-views", "peak-detector"} <= set(
        shipped_studies())
    st = load_study("laser-angle")  # the file issue 3 shipped keeps working
    assert st.kind == "laser" and len(st.runs) == 6
    assert [r.params["rig.triangulation_angle_deg"] for r in st.runs] == [10, 20, 30, 40, 50, 60]
    for name in shipped_studies():
        if is_suite(name):
            assert all(load_study(m).runs for m in load_suite(name).studies())
        else:
            assert load_study(name).runs


def test_failing_run_is_recorded_and_the_study_goes_on(tmp_path):
    spec = _spec(tmp_path, GRID.replace("sleep = 0.0", "sleep = 0.0\nfail_above = 2.5"))
    res = run_study(load_study(spec), tmp_path / "out", workers=2)
    df = res["table"]
    assert len(df) == 6 and res["failed"] == 2
    bad = df[df["status"] == "failed"]
    assert set(bad["x"]) == {3} and bad["error"].str.contains("above fail_above").all()
    good = df[df["status"] == "ok"]
    assert (good["y"] == good["reconstruct.scale"] * good["x"] ** 2).all()
    # CSV and Parquet agree; one plot per metric and swept parameter
    csv = pd.read_csv(tmp_path / "out" / "results.csv")
    pq = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert list(csv["run_id"]) == list(pq["run_id"]) == list(df["run_id"])
    plots = {p.name for p in (tmp_path / "out" / "plots").iterdir()}
    assert {"y_vs_x.png", "y_vs_reconstruct.scale.png", "x_vs_x.png"} <= plots
    # a metric named like a swept parameter gets its own column
    assert (good["metric:x"] == good["x"]).all()
    # a second start skips every recorded run, failures included
    res2 = run_study(load_study(spec), tmp_path / "out", workers=2)
    assert res2["executed"] == 0 and res2["done_before"] == 6


def test_a_run_that_kills_its_worker_is_recorded_as_failed(tmp_path):
    spec = _spec(tmp_path, GRID.replace("sleep = 0.0", "sleep = 0.0\ncrash_at = 2"))
    df = run_study(load_study(spec), tmp_path / "out", workers=2)["table"]
    assert len(df) == 6
    bad = df[df["status"] == "failed"]
    assert set(bad["x"]) == {2} and bad["error"].str.contains("worker process died").all()
    assert (df[df["x"] != 2]["status"] == "ok").all()


KILL = """
[study]
name = "kill"
kind = "_test"
[base]
sleep = 0.5
marker_dir = "{markers}"
[sweep]
x = [{xs}]
"""


def test_resume_after_kill_9_runs_every_run_exactly_once(tmp_path, capsys):
    """Kill the whole study (process group, SIGKILL) once the first run is recorded, then
    resume: no recorded run is executed again, every other run is, and none is lost.

    Each execution leaves a marker file. A run the kill caught after its marker but
    before its record is legitimately run again (its result was never recorded), so
    only the recorded runs must have exactly one marker."""
    xs = list(range(1, 11))
    markers = tmp_path / "markers"
    spec = _spec(tmp_path, KILL.format(markers=markers, xs=", ".join(map(str, xs))))
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "scanamp", "-q", "study", str(spec), "--out",
                             str(out), "--workers", "2"], cwd=tmp_path, env=env,
                            start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while not list((out / "runs").glob("*.json")) if (out / "runs").is_dir() else True:
        assert proc.poll() is None, "the study ended before the kill"
        assert time.monotonic() < deadline, "no run recorded in time"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    time.sleep(0.3)
    recorded = {json.loads(p.read_text())["metrics"]["y"] ** 0.5
                for p in (out / "runs").glob("*.json")}
    n_killed = len(recorded)
    assert 1 <= n_killed < len(xs), "the kill should leave a partial study"
    assert not (out / "results.csv").exists()
    assert (out / ".scanamp.json").is_file()  # marked as ours before the first run
    from scanamp.cli import main

    assert main(["study", str(spec), "--out", str(out), "--workers", "2"]) == 0  # resumes
    assert (f"({n_killed} recorded before, {len(xs) - n_killed} run now"
            in capsys.readouterr().out)
    done = Counter(float(p.name.split("-x")[1][:-5]) for p in markers.iterdir())
    assert set(done) == set(map(float, xs))  # every run executed
    assert all(done[x] == 1 for x in recorded)  # a recorded run is never executed again
    assert all(done[x] <= 2 for x in done)  # at most once more, if killed unrecorded
    df = pd.read_csv(out / "results.csv")
    assert sorted(df["x"]) == xs and (df["status"] == "ok").all()
    assert sorted(df["y"]) == [x * x for x in xs]
    # no temporary leftovers of the atomic writes
    assert not [p for p in (out / "runs").iterdir() if p.name.startswith(".")]


def test_dask_local_cluster_runs_the_study(tmp_path):
    import dask
    from distributed import Client, LocalCluster

    spec = _spec(tmp_path, GRID.replace("sleep = 0.0", "sleep = 0.0\nfail_above = 2.5"))
    # the cluster's scratch (scheduler and workers) in the test's folder, not the system's
    with dask.config.set({"temporary-directory": str(tmp_path / "dask")}), \
            LocalCluster(n_workers=1, threads_per_worker=1, host="127.0.0.1",
                         dashboard_address=None, processes=True,
                         local_directory=tmp_path / "dask") as cluster:
        res = run_study(load_study(spec), tmp_path / "out", scheduler=cluster.scheduler_address)
        with Client(cluster.scheduler_address) as client:
            assert len(client.scheduler_info()["workers"]) == 1
    df = res["table"]
    assert len(df) == 6 and list(df["status"]).count("failed") == 2
    recs = [json.loads(p.read_text()) for p in (tmp_path / "out" / "runs").glob("*.json")]
    assert len(recs) == 6 and {r["run_id"] for r in recs} == set(df["run_id"])
    ok = df[df["status"] == "ok"]
    assert (ok["y"] == ok["reconstruct.scale"] * ok["x"] ** 2).all()


def _cli_error(capsys, *argv):
    code = main(list(argv))
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


@pytest.mark.parametrize("text, field", [
    ("[study]\nkind='_test'\n[sweep]\n", "sweep"),
    ("[study]\nkind='_test'\n[sweep]\nx = []\n", "sweep.x"),
    ("[study]\nkind='_test'\n[sweep]\nx = 3\n", "sweep.x"),
    ("[study]\nkind='_test'\n[sweep]\nnope = [1, 2]\n", "sweep.nope"),
    ("[study]\nkind='_test'\n[sweep]\n'reconstruct.nope' = [1, 2]\n", "sweep.reconstruct.nope"),
    ("[study]\nkind='laser'\n[sweep]\n'rig.triangulation_angel_deg' = [10, 20]\n",
     "sweep.rig.triangulation_angel_deg"),
    ("[study]\nkind='laser'\n[sweep]\n'rig.triangulation_angle_deg' = [10, 95]\n",
     "sweep.rig.triangulation_angle_deg"),
    ("[study]\nkind='laser'\n[sweep]\n'reconstruct.detector' = ['gaussian', 'sobel']\n",
     "sweep.reconstruct.detector"),
    ("[study]\nkind='sfm'\n[base]\nviewz = 3\n[sweep]\nviews = [6, 12]\n", "base.viewz"),
    ("[study]\nkind='sonar'\n[sweep]\nx = [1]\n", "study.kind"),
    ("[study]\nkind='_test'\nmode='random'\nn=3\n[sweep]\nx = [1, 2]\n", "sweep.x"),
    ("[study]\nkind='laser'\n[sweep]\n'material.preset' = ['matte', 'velvet']\n",
     "sweep.material.preset"),
    ("[study]\nkind='laser'\n[sweep]\n'material.shine' = [1, 2]\n", "sweep.material.shine"),
    ("[study]\nkind='laser'\n[sweep]\n'material.roughness' = [0.5, 2.0]\n",
     "sweep.material.roughness"),
    ("[study]\nkind='laser'\n[base]\n'material.object' = 'teapot'\n"
     "[sweep]\n'material.preset' = ['matte']\n", "base.material.object"),
])
def test_bad_study_exits_2_with_one_line_naming_file_and_field(tmp_path, capsys, text, field):
    spec = _spec(tmp_path, text)
    code, err = _cli_error(capsys, "study", str(spec), "--out", str(tmp_path / "o"))
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(f"error: {spec}: {field}:"), err[0]
    assert not (tmp_path / "o").exists()


def test_unreachable_scheduler_exits_2_quickly(tmp_path, capsys):
    spec = _spec(tmp_path, GRID)
    code, err = _cli_error(capsys, "study", str(spec), "--out", str(tmp_path / "o"),
                           "--scheduler", "tcp://127.0.0.1:1", "--timeout", "2")
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith("error: --scheduler: cannot reach") and "127.0.0.1:1" in err[0]


def test_a_metric_no_run_reports_is_warned_about_with_a_suggestion(tmp_path, caplog):
    spec = _spec(tmp_path, GRID.replace('metrics = ["y", "x"]', 'metrics = ["y", "yy"]'))
    with caplog.at_level("WARNING", logger="scanamp.study"):
        res = run_study(load_study(spec), tmp_path / "out", workers=1)
    assert res["table"]["yy"].isna().all() and res["table"]["y"].notna().all()
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) == 1, warned
    assert "metric yy is in none of the 6 finished runs' reports; did you mean y?" in warned[0]


def test_material_overrides_change_the_scanned_object_only():
    from scanamp.study.kinds import _scene, material_overrides

    m = material_overrides({"material.preset": "subsurface-1mm", "material.ior": 1.3,
                            "rig.steps": 10})
    assert m == {"brdf": "subsurface", "mfp": 1e-3, "ior": 1.3}
    plain, _ = _scene("object")
    changed, _ = _scene("object", m)
    mats = {o.name: o.material for o in changed.render_scene.objects}
    before = {o.name: o.material for o in plain.render_scene.objects}
    assert mats["object"].brdf == "subsurface" and mats["object"].mfp == 1e-3
    assert mats["object"].kind == before["object"].kind            # its texture is kept
    assert all(mats[n].brdf == before[n].brdf for n in mats if n != "object")


SUITE = """
[suite]
name = "both"
rows = "x"

[[method]]
name = "plain"
study = "a.toml"
fscore = "y"
precision = "x"
recall = "x"
bias = "y"

[[method]]
name = "scaled"
study = "b.toml"
fscore = "y"
precision = "x"
recall = "x"
bias = "x"
"""

MEMBER = """
[study]
name = "{name}"
kind = "_test"
[base]
"reconstruct.scale" = {scale}
[sweep]
x = [0.25, 0.5]
[output]
metrics = ["y", "x"]
"""


def test_a_suite_runs_its_studies_and_sets_them_side_by_side(tmp_path, capsys):
    _spec(tmp_path, MEMBER.format(name="a", scale=1.0), "a.toml")
    _spec(tmp_path, MEMBER.format(name="b", scale=10.0), "b.toml")
    suite = _spec(tmp_path, SUITE, "suite.toml")
    assert is_suite(suite) and not is_suite(tmp_path / "a.toml")
    out = tmp_path / "out"
    assert main(["study", str(suite), "--out", str(out)]) == 0
    assert "suite 'both'" in capsys.readouterr().out
    table = pd.read_csv(out / "results.csv")
    assert list(table["method"]) == ["plain", "plain", "scaled", "scaled"]
    assert list(table["x"]) == [0.25, 0.5, 0.25, 0.5]
    # the measures come from each member's own columns: y = scale x^2
    assert list(table["fscore"]) == [0.0625, 0.25, 0.625, 2.5]
    assert list(table["outliers"]) == list(table["dropout"]) == [0.75, 0.5, 0.75, 0.5]
    assert list(table["bias"]) == [0.0625, 0.25, 0.25, 0.5]
    assert (out / "a" / "results.csv").is_file() and (out / "b" / "results.csv").is_file()
    assert {p.name for p in (out / "plots").iterdir()} == {
        "fscore.png", "outliers.png", "dropout.png", "bias.png"}
    # resumable: a second run runs nothing again
    assert main(["study", str(suite), "--out", str(out)]) == 0
    assert "0 run now" in capsys.readouterr().out


@pytest.mark.parametrize("edit, field", [
    (("rows = \"x\"", "rows = \"z\""), "method[0].study"),
    (("fscore = \"y\"", "fscore = \"w\""), "method[0].fscore"),
    (("bias = \"x\"", "bias = \"x\"\ncolour = \"red\""), "method[1]"),
])
def test_a_bad_suite_names_the_file_and_field(tmp_path, capfd, edit, field):
    _spec(tmp_path, MEMBER.format(name="a", scale=1.0), "a.toml")
    _spec(tmp_path, MEMBER.format(name="b", scale=10.0), "b.toml")
    suite = _spec(tmp_path, SUITE.replace(*edit, 1), "suite.toml")
    assert main(["study", str(suite), "--out", str(tmp_path / "out")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "suite.toml" in err[0] and field in err[0], err
    assert not (tmp_path / "out").exists()
