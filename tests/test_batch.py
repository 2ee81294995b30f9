"""``rotavat batch``: discovery, outputs equal to the single-sequence library calls (chunked or not),
resume markers, failure isolation, the dataset aggregate, and Dask results equal to the local ones."""

from __future__ import annotations

import json
import os
import shutil
import sys
import zipfile
from pathlib import Path

import _format_fixtures as F
import numpy as np
import pytest
import yaml
from _cli import invoke
from conftest import tree_hash

from rotavat_cli.alignment import AlignOptions, align_sequence
from rotavat_cli.batch import MARKER, aggregate_rows, discover_sequences
from rotavat_cli.metrics.evaluate import evaluate
from rotavat_cli.plain import to_plain
from rotavat_cli.sequence import open_sequence, read_camera_yaml
from rotavat_cli.synth import SynthOptions, write_synth_scene

RELS = ["a/s1", "a/s2", "b"]
FAST = ["--steps", "calibrate,align,eval"]  # render costs ~1 s a sequence: only where it is checked


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """pred/<rel> and gt/<rel> for three tiny synthetic scenes (3 frames x 3 people), one seed each."""
    root = tmp_path_factory.mktemp("dataset")
    for seed, rel in enumerate(RELS):
        write_synth_scene(root / "tmp", SynthOptions(seed=seed, frames=3, people=3))
        for side in ("pred", "gt"):
            (root / side / rel).parent.mkdir(parents=True, exist_ok=True)
            os.replace(root / "tmp" / side, root / side / rel)
        shutil.rmtree(root / "tmp")
    return root


@pytest.fixture
def data(dataset, tmp_path) -> Path:
    """A private copy of the dataset (for tests that touch or break inputs)."""
    shutil.copytree(dataset, tmp_path / "data")
    return tmp_path / "data"


def batch(runner, root: Path, out: Path, *args):
    """``rotavat batch ROOT --out OUT ...``, in-process."""
    return invoke(runner, "batch", root, "--out", out, *args)


def npz_payloads(path: Path) -> dict[str, bytes]:
    """The members of an .npz (header + data of every array): its bytes without the zip timestamps."""
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def assert_same_tree(a: Path, b: Path) -> int:
    """Every file under ``a`` equals the one under ``b`` byte for byte (npz: member by member)."""
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for rel in files:
        if rel.suffix == ".npz":
            assert npz_payloads(a / rel) == npz_payloads(b / rel), rel
        else:
            assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel
    return len(files)


def metrics_of(out: Path, rel: str) -> list[dict]:
    """The metric and camera-error blocks of OUT/<rel>/eval/metrics.json, one per prediction."""
    data = json.loads((out / rel / "eval" / "metrics.json").read_text())
    return [{k: p[k] for k in ("metrics", "camera", "matched", "missed", "false_positives")} for p in data["predictions"]]


# ---- discovery ------------------------------------------------------------------------------------
def test_discovery_finds_npz_and_obj_sequences_and_skips_the_rest(tmp_path):
    root = tmp_path / "root"
    for rel in ("cam1", "site/cam2", "site/deep/cam3", ".hidden/cam", "_scratch/cam", "out/cam"):
        (root / rel).mkdir(parents=True)
        np.savez(root / rel / "000000.npz", person_ids=np.zeros(0, np.int64))
    (root / "site" / "cam2" / "nested").mkdir()  # inside a sequence: never searched
    np.savez(root / "site" / "cam2" / "nested" / "000000.npz", person_ids=np.zeros(0, np.int64))
    (root / "objcam" / "000000").mkdir(parents=True)  # OBJ form: frame folders of per-person OBJ files
    (root / "objcam" / "000000" / "0.obj").write_text("v 0 0 1\nv 1 0 1\nv 0 1 1\nf 1 2 3\n")
    (root / "notes").mkdir()
    (root / "notes" / "readme.txt").write_text("not a sequence")
    found = discover_sequences(root, exclude=[root / "out"])
    assert [rel for rel, _ in found] == ["cam1", "objcam", "site/cam2", "site/deep/cam3"]
    assert discover_sequences(root / "cam1") == [(".", root / "cam1")]  # ROOT itself is one sequence


def test_discovery_with_an_importer_format(tmp_path, scene):
    F.write_bev(tmp_path / "root" / "day1" / "cam1", scene, (640, 480))  # a folder of per-image results
    (tmp_path / "root" / "day2").mkdir()
    F.write_cliff(tmp_path / "root" / "day2" / "video_cliff.npz", scene, (640, 480))
    (tmp_path / "root" / "day2" / "notes.txt").write_text("x")
    assert [rel for rel, _ in discover_sequences(tmp_path / "root", "bev")] == ["day1/cam1"]
    assert [rel for rel, _ in discover_sequences(tmp_path / "root", "cliff")] == ["day2/video_cliff"]  # suffix dropped


# ---- outputs ------------------------------------------------------------------------------------
def test_batch_outputs_equal_the_single_sequence_calls(dataset, tmp_path, runner):
    """Chunks of one frame (align and eval) give what align_sequence and evaluate give on the whole sequence."""
    before = tree_hash(dataset)
    out = tmp_path / "out"
    result = batch(runner, dataset / "pred", out, "--gt-root", dataset / "gt", "--jobs", "1", "--chunk-frames", "1", "--json")
    assert result.exit_code == 0, result.stderr
    assert tree_hash(dataset) == before  # inputs untouched
    summary = json.loads(result.stdout)
    counts = summary["counts"]
    assert (counts["sequences"], counts["done"], counts["frames"], counts["people"]) == (3, 3, 9, 27)
    assert counts["aligned"] + sum(counts["flagged"].values()) == 27
    for rel in RELS:
        seq = open_sequence(dataset / "pred" / rel)
        camera, fit = read_camera_yaml(out / rel / "camera.yaml")
        align_sequence(seq, camera, tmp_path / "ref" / rel, AlignOptions(jobs=1), camera_fit=fit)
        assert assert_same_tree(out / rel / "aligned", tmp_path / "ref" / rel) == 7  # 3 frames, people.csv, camera, meta, marker
        want = [evaluate(open_sequence(dataset / "pred" / rel), open_sequence(dataset / "gt" / rel)),
                evaluate(open_sequence(out / rel / "aligned"), open_sequence(dataset / "gt" / rel))]
        got = metrics_of(out, rel)
        for g, w in zip(got, want):
            assert g["metrics"] == to_plain(w.metrics)  # equal floats, not close ones
            assert (g["matched"], g["missed"], g["false_positives"]) == (w.matched, w.missed, w.false_positives)
        assert list(got[1]["camera"]) and not got[0]["camera"]  # the aligned prediction carries the estimated camera
        marker = json.loads((out / rel / MARKER).read_text())
        assert marker["steps"] == ["calibrate", "align", "eval", "render"] and marker["row"]["status"] == "done"
        assert sorted(p.name for p in (out / rel / "render").iterdir()) == [".rotavat-output", "000000.png"]
        assert not list((out / rel).glob(".*partial*")) and not (out / rel / ".aligned.chunks").exists()
    report = json.loads((out / "batch_report.json").read_text())
    assert [r["sequence"] for r in report["rows"]] == RELS
    md = (out / "batch_report.md").read_text()
    assert "## Dataset aggregate" in md and "| w_mpjpe (paper, mm) |" in md and "`a/s2` | done" in md


def test_aggregate_is_people_weighted_with_pooled_detection():
    def row(name, matched, missed, fp, w_mpjpe, cam_pct, focal, people):
        ev = {"matched": matched, "missed": missed, "false_positives": fp, "people_gt": matched + missed,
              "people_pred": matched + fp, "metrics": {"w_mpjpe": w_mpjpe, "mpjpe": w_mpjpe / 10}, "camera": {"cam_focal_pct": cam_pct}}
        return {"sequence": name, "status": "done", "frames": 10, "people": people, "eval": {"before": ev},
                "camera": {"focal_px": focal, "pitch_deg": 20.0, "roll_deg": 0.0, "height_m": 5.0}}
    rows = [row("x", 30, 0, 0, 100.0, 2.0, 1000.0, 30), row("y", 10, 10, 5, 500.0, None, 2000.0, 10),
            {"sequence": "z", "status": "failed", "reason": "boom", "frames": None, "people": None}]
    agg = aggregate_rows(rows)
    assert agg["counts"] == {"sequences": 3, "done": 2, "skipped": 0, "failed": 1, "frames": 20, "people": 40}
    before = agg["eval"]["before"]
    assert before["metrics"]["w_mpjpe"] == pytest.approx((30 * 100.0 + 10 * 500.0) / 40)  # weighted by matched people
    assert before["metrics"]["precision"] == pytest.approx(40 / 45) and before["metrics"]["recall"] == pytest.approx(40 / 50)
    assert before["metrics"]["nmje"] == pytest.approx(before["metrics"]["mpjpe"] / before["metrics"]["f1"])
    assert before["camera"]["cam_focal_pct"]["n"] == 1  # a missing camera error is left out, not zero
    cams = agg["cameras"]
    assert cams["focal_px"]["mean"] == 1500.0 and cams["focal_px"]["weighted_mean"] == pytest.approx(1250.0)
    assert [c["sequence"] for c in cams["per_sequence"]] == ["x", "y"]


# ---- resume ---------------------------------------------------------------------------------------
def test_resume_skips_complete_sequences_and_redoes_changed_ones(data, tmp_path, runner):
    out, args = tmp_path / "out", ["--gt-root", data / "gt", "--jobs", "1", *FAST, "--json"]
    assert batch(runner, data / "pred", out, *args).exit_code == 0
    stamps = {rel: (out / rel / MARKER).stat().st_mtime_ns for rel in RELS}

    again = json.loads(batch(runner, data / "pred", out, *args).stdout)
    assert again["counts"]["skipped"] == 3 and again["counts"]["done"] == 0
    assert {rel: (out / rel / MARKER).stat().st_mtime_ns for rel in RELS} == stamps
    assert again["aggregate"]["eval"] == json.loads((out / "batch_report.json").read_text())["aggregate"]["eval"]

    # A newer input frame: only that sequence again. Stamped an hour ahead of the clock: the rerun's marker is then
    # older than its input, which must not matter (the fingerprint decides; it once depended on the rerun's speed).
    frame = data / "pred" / "b" / "000001.npz"
    os.utime(frame, ns=(frame.stat().st_atime_ns, frame.stat().st_mtime_ns + 3600 * 10**9))
    (out / "a" / "s1" / "aligned" / "people.csv").unlink()  # an output gone: never complete
    rerun = json.loads(batch(runner, data / "pred", out, *args).stdout)
    assert (rerun["counts"]["done"], rerun["counts"]["skipped"]) == (2, 1)
    assert (out / "a" / "s2" / MARKER).stat().st_mtime_ns == stamps["a/s2"]

    fewer = json.loads(batch(runner, data / "pred", out, *args[:4], "--steps", "calibrate", "--json").stdout)
    assert fewer["counts"]["skipped"] == 3  # the markers list more steps than asked for
    config = tmp_path / "c.yaml"
    config.write_text("calibrate:\n  person_height_m: 1.75\n")  # an option that changes the results
    changed = json.loads(batch(runner, data / "pred", out, *args, "--config", config).stdout)
    assert changed["counts"]["done"] == 3
    forced = json.loads(batch(runner, data / "pred", out, *args, "--config", config, "--force").stdout)
    assert forced["counts"]["done"] == 3


def test_partial_outputs_never_look_complete(data, tmp_path, runner):
    out = tmp_path / "out"
    args = ["--gt-root", data / "gt", "--jobs", "1", "--steps", "calibrate,align", "--json"]
    assert batch(runner, data / "pred", out, *args).exit_code == 0
    (out / "b" / MARKER).unlink()  # as if the run had stopped before the marker
    (out / "b" / ".aligned.chunks" / "chunk-000000").mkdir(parents=True)  # and left staging behind
    result = json.loads(batch(runner, data / "pred", out, *args).stdout)
    assert result["counts"]["done"] == 1 and result["counts"]["skipped"] == 2
    assert (out / "b" / MARKER).exists() and not (out / "b" / ".aligned.chunks").exists()


# ---- failures -------------------------------------------------------------------------------------
def test_a_failing_sequence_is_reported_and_the_others_finish(data, tmp_path, runner):
    """Process pool of 2: a truncated frame fails its sequence only; exit 1, reason on one line."""
    broken = data / "pred" / "a" / "s2" / "000001.npz"
    original = broken.read_bytes()
    broken.write_bytes(original[:100])
    out = tmp_path / "out"
    result = batch(runner, data / "pred", out, "--gt-root", data / "gt", "--jobs", "2", "--chunk-frames", "2", *FAST)
    assert result.exit_code == 1
    assert "a/s2 failed:" in result.stderr and "000001.npz" in result.stderr
    assert "[3/3]" in result.stderr and "1 of 3 sequences failed" in result.stderr
    report = json.loads((out / "batch_report.json").read_text())
    status = {r["sequence"]: r for r in report["rows"]}
    assert [status[rel]["status"] for rel in RELS] == ["done", "failed", "done"]
    assert "000001.npz" in status["a/s2"]["reason"] and "\n" not in status["a/s2"]["reason"]
    assert not (out / "a" / "s2" / MARKER).exists() and (out / "b" / MARKER).exists()
    assert report["aggregate"]["counts"]["failed"] == 1 and report["aggregate"]["eval"]["after"]["sequences"] == 2
    assert "## Failed" in (out / "batch_report.md").read_text()
    assert {w["peak_rss_mb"] > 0 for w in report["worker_stats"]} == {True}

    broken.write_bytes(original)  # fixed: only the failed one runs again
    again = invoke(runner, "batch", data / "pred", "--out", out, "--gt-root", data / "gt", "--jobs", "1", *FAST, "--json")
    assert again.exit_code == 0 and json.loads(again.stdout)["counts"]["done"] == 1


@pytest.mark.parametrize("args,message", [
    (["missing_root"], "no such directory"),
    (["empty"], "no sequences"),
    (["pred", "--steps", "eval"], "needs --gt-root"),
    (["pred", "--steps", "align,fly"], "unknown step"),
    (["pred", "--executor", "slurm"], "--executor: must be one of local, dask"),
    (["pred", "--from", "nosuchtool"], "unknown format"),
])
def test_usage_errors_exit_2(data, tmp_path, runner, monkeypatch, args, message):
    monkeypatch.chdir(data)
    (data / "empty").mkdir()
    result = invoke(runner, "batch", *args, "--out", tmp_path / "out")
    assert result.exit_code == 2
    last = result.stderr.strip().splitlines()[-1]  # the one-line error (after any "eval skipped" note)
    assert last.startswith("error:") and message in last


def test_dask_without_dask_says_how_to_install(data, tmp_path, runner, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    result = batch(runner, data / "pred", tmp_path / "out", "--executor", "dask", "--steps", "calibrate")
    assert result.exit_code == 2 and "pip install 'rotavat[dask]'" in result.stderr


def test_eval_is_dropped_from_the_default_steps_without_ground_truth(data, tmp_path, runner):
    result = batch(runner, data / "pred", tmp_path / "out", "--jobs", "1", "--chunk-frames", "2")
    assert result.exit_code == 0, result.stderr
    assert "eval skipped: no --gt-root" in result.stderr
    assert (tmp_path / "out" / "b" / "render" / "000000.png").exists() and not (tmp_path / "out" / "b" / "eval").exists()


def test_align_without_the_calibrate_step_uses_each_sequence_s_own_camera(data, tmp_path, runner):
    """A sequence with its camera.yaml is aligned into that camera, read once and handed to every chunk."""
    for rel in RELS:
        shutil.copy(data / "gt" / rel / "camera.yaml", data / "pred" / rel / "camera.yaml")
    result = batch(runner, data / "pred", tmp_path / "out", "--jobs", "1", "--chunk-frames", "2", "--steps", "align")
    assert result.exit_code == 0, result.stderr
    report = json.loads((tmp_path / "out" / "batch_report.json").read_text())
    for row in report["rows"]:
        assert row["camera"]["origin"] == "given"
        given = open_sequence(data / "pred" / row["sequence"]).camera
        aligned = open_sequence(tmp_path / "out" / row["sequence"] / "aligned").camera
        assert aligned == given


def test_import_format_sequences_are_converted_into_the_output_tree(tmp_path, runner, model, model_path):
    scene = F.bev_scene(model, 8, 5)
    for rel, frames in (("site/cam1", scene[:4]), ("cam2", scene[4:])):
        F.write_bev(tmp_path / "bev" / rel, frames, (640, 480))
    result = invoke(runner, "batch", tmp_path / "bev", "--out", tmp_path / "out", "--from", "bev", "--smpl-model", model_path,
                    "--image-size", "640", "480", "--steps", "calibrate,align", "--jobs", "1", "--json")
    assert result.exit_code == 0, result.stderr
    for rel in ("site/cam1", "cam2"):
        assert len(open_sequence(tmp_path / "out" / rel / "input")) == 4
        assert (tmp_path / "out" / rel / "aligned" / "people.csv").exists()
        est, _ = read_camera_yaml(tmp_path / "out" / rel / "camera.yaml")
        assert np.rad2deg(est.pitch_rad) == pytest.approx(15.0, abs=3.0)


# ---- Dask -----------------------------------------------------------------------------------------
@pytest.mark.slow  # a real Dask cluster: its scheduler and worker processes
def test_dask_cluster_results_equal_the_local_ones(dataset, tmp_path, runner):
    """A real LocalCluster on loopback, 2 worker processes, per-chunk tasks: meshes equal byte for byte."""
    distributed = pytest.importorskip("distributed")
    import logging

    local = tmp_path / "local"
    common = ["--gt-root", dataset / "gt", *FAST]
    assert batch(runner, dataset / "pred", local, *common, "--jobs", "2", "--chunk-frames", "100").exit_code == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None, silence_logs=logging.ERROR) as cluster:
        result = batch(runner, dataset / "pred", tmp_path / "dask", *common, "--executor", "dask",
                       "--scheduler", cluster.scheduler_address, "--chunk-frames", "2", "--json")
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["counts"]["done"] == 3 and len(report["workers"]) == 2  # both workers took tasks
    for rel in RELS:
        assert assert_same_tree(local / rel / "aligned", tmp_path / "dask" / rel / "aligned") == 7
        assert (local / rel / "camera.yaml").read_bytes() == (tmp_path / "dask" / rel / "camera.yaml").read_bytes()
        assert metrics_of(local, rel) == metrics_of(tmp_path / "dask", rel)
    assert (json.loads((local / "batch_report.json").read_text())["aggregate"]
            == json.loads((tmp_path / "dask" / "batch_report.json").read_text())["aggregate"])


@pytest.mark.slow  # a real Dask cluster: its scheduler and worker processes
def test_rotavat_local_cluster_workers_run_without_dask_malloc_trim_and_housekeeping(monkeypatch):
    """rotavat's own LocalCluster: one BLAS thread per worker as Dask sets it, glibc's malloc left as is,
    no stack profiler and a slow event-loop tick in the workers."""
    distributed = pytest.importorskip("distributed")
    from rotavat_cli.batch.executors import local_cluster

    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    keys = ("MALLOC_TRIM_THRESHOLD_", "OPENBLAS_NUM_THREADS")

    def worker_state() -> dict:
        import dask

        return {"env": {k: os.environ.get(k) for k in keys},
                "profile": dask.config.get("distributed.worker.profile.enabled"),
                "tick": dask.config.get("distributed.admin.tick.interval")}

    with local_cluster(1) as cluster, distributed.Client(cluster) as client:
        (state,) = client.run(worker_state).values()
    assert state == {"env": {"MALLOC_TRIM_THRESHOLD_": None, "OPENBLAS_NUM_THREADS": "1"},
                     "profile": False, "tick": "500ms"}


def test_pool_workers_get_one_blas_thread_and_the_driver_env_is_restored(monkeypatch):
    """--jobs N > 1: each spawned worker runs single-threaded BLAS; a value the user set wins; close restores."""
    from rotavat_cli.batch.executors import POOL_WORKER_ENVIRON, _PoolExecutor

    for key in POOL_WORKER_ENVIRON:
        monkeypatch.delenv(key, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")  # the user's own choice
    pool = _PoolExecutor(2)
    try:
        env = {key: pool.submit(os.getenv, key).result() for key in POOL_WORKER_ENVIRON}
    finally:
        pool.close()
    assert (env["OMP_NUM_THREADS"], env["OPENBLAS_NUM_THREADS"], env["MKL_NUM_THREADS"]) == ("1", "1", "3")
    assert "OMP_NUM_THREADS" not in os.environ and "OPENBLAS_NUM_THREADS" not in os.environ
    assert os.environ["MKL_NUM_THREADS"] == "3"


def test_ground_truth_in_a_tool_format_is_found_and_imported_with_gt_from(tmp_path, runner, model, model_path):
    """--gt-from: GT/<rel> in a format's own files (here a folder per sequence) is found by its importer,
    imported into OUT/<rel>/gt, and scores the prediction (the same scene: every person matched, 0 mm)."""
    scene = F.bev_scene(model, 6, 4, seed=5)
    for rel, frames in (("site/cam1", scene[:3]), ("cam2", scene[3:])):
        F.write_bev(tmp_path / "pred" / rel, frames, (640, 480))
        F.write_bev(tmp_path / "gt" / rel, frames, (640, 480))
    args = ["--out", tmp_path / "out", "--from", "bev", "--smpl-model", model_path, "--image-size", "640", "480",
            "--steps", "eval", "--jobs", "1", "--json"]
    result = invoke(runner, "batch", tmp_path / "pred", "--gt-root", tmp_path / "gt", "--gt-from", "bev", *args)
    assert result.exit_code == 0, result.stderr
    for rel in ("site/cam1", "cam2"):
        assert len(open_sequence(tmp_path / "out" / rel / "gt")) == 3
        (before,) = metrics_of(tmp_path / "out", rel)
        assert before["matched"] == 12 and before["metrics"]["w_mpjpe"] == pytest.approx(0.0, abs=1e-3)
    missing = invoke(runner, "batch", tmp_path / "pred", "--gt-from", "bev", *args)
    assert missing.exit_code == 2 and "--gt-from needs --gt-root" in missing.stderr


def test_dataset_aggregate_follows_the_eval_protocol():
    """Under eval.protocol agora the dataset's F1 and NMJE follow AGORA's rounding of the summed counts."""
    from rotavat_cli.batch.report import aggregate_rows

    def row(name, matched, missed, fp, mpjpe):
        ev = {"protocol": "agora", "matched": matched, "missed": missed, "false_positives": fp, "people_gt": matched + missed,
              "people_pred": matched + fp, "metrics": {"mpjpe": mpjpe, "pa_mpjpe": mpjpe / 2}, "camera": {}}
        return {"sequence": name, "status": "done", "frames": 1, "people": matched, "eval": {"before": ev}}

    agg = aggregate_rows([row("a", 30, 3, 2, 60.0), row("b", 10, 0, 7, 80.0)])["eval"]["before"]
    # pooled: matched 40, missed 3, false positives 9; mpjpe (30 * 60 + 10 * 80) / 40 = 65.0
    precision, recall, f1 = round(40 / 49, 2), round(40 / 43, 2), round(40 / (40 + 0.5 * 12), 2)
    assert agg["protocol"] == "agora"
    assert (agg["metrics"]["precision"], agg["metrics"]["recall"], agg["metrics"]["f1"]) == (precision, recall, f1)
    assert agg["metrics"]["mpjpe"] == 65.0 and agg["metrics"]["nmje"] == round(65.0 / f1, 1)
    assert "pve" not in agg["metrics"] and "nmve" not in agg["metrics"]  # AGORA's MVE needs its vertex subset


# ---- the camera gate ------------------------------------------------------------------------------
def _implausible_calibration_of(rel: str, monkeypatch) -> None:
    """Calibrating ``rel`` (in this process: --jobs 1) finds the camera implausible; the others as they are."""
    from dataclasses import replace

    import rotavat_cli.batch.tasks as tasks
    from _camera_gate import FINDINGS

    real = tasks.calibrate_sequence

    def calibrate_sequence(seq, options):
        calib = real(seq, options)
        if seq.path.as_posix().endswith(rel):
            return replace(calib, result=replace(calib.result, implausible=FINDINGS))
        return calib

    monkeypatch.setattr(tasks, "calibrate_sequence", calibrate_sequence)  # the batch task's own name for it


def test_an_implausible_camera_fails_its_sequence_only_until_accepted(data, tmp_path, runner, monkeypatch):
    from _camera_gate import FINDINGS, assert_doc_link_exists, assert_named_flags_exist

    _implausible_calibration_of("a/s2", monkeypatch)
    out, args = tmp_path / "out", ["--jobs", "1", "--steps", "calibrate,align"]
    result = batch(runner, data / "pred", out, *args)
    assert result.exit_code == 1
    (line,) = [line for line in result.stderr.splitlines() if "a/s2 failed:" in line]  # one line, printed as it happens
    assert f"prepare: the camera calibrated from {data / 'pred' / 'a' / 's2'} ({out / 'a' / 's2' / 'camera.yaml'}): " \
           f"implausible camera ({FINDINGS[0]}; {FINDINGS[1]}); give what you know: rerun rotavat batch {data / 'pred'} " \
           f"--out {out}" in line
    assert "--focal PX --camera-height M [--pitch DEG]" in line and "--camera FILE" in line and "--accept-camera" in line
    report = json.loads((out / "batch_report.json").read_text())
    rows = {r["sequence"]: r for r in report["rows"]}
    assert [rows[rel]["status"] for rel in RELS] == ["done", "failed", "done"]
    assert_named_flags_exist(rows["a/s2"]["reason"])
    assert_doc_link_exists(rows["a/s2"]["reason"])
    assert rows["a/s2"]["camera"]["implausible"] == list(FINDINGS) and rows["a/s1"]["camera"]["implausible"] == []
    assert not (out / "a" / "s2" / "aligned").exists() and (out / "a" / "s2" / "camera.yaml").exists()
    md = (out / "batch_report.md").read_text()
    assert "## Camera checks and warnings\n\n" in md  # the other sequences' warnings may come first
    assert f"\n- `a/s2`: implausible camera ({FINDINGS[0]}; {FINDINGS[1]}), refused" in md

    result = batch(runner, data / "pred", out, *args, "--accept-camera", "--json")  # the refusal's last advice
    assert result.exit_code == 0, result.stderr
    counts = json.loads(result.stdout)["counts"]
    assert (counts["done"], counts["skipped"], counts["failed"]) == (1, 2, 0)
    fit = read_camera_yaml(out / "a" / "s2" / "aligned" / "camera.yaml")[1]
    assert fit["implausible"] == list(FINDINGS) and fit["accepted"] is True
    row = {r["sequence"]: r for r in json.loads((out / "batch_report.json").read_text())["rows"]}["a/s2"]
    assert row["status"] == "done" and row["camera"]["accepted"] is True
    assert "), used (--accept-camera)" in (out / "batch_report.md").read_text()


def test_known_camera_values_reach_every_sequence_s_calibration(data, tmp_path, runner):
    result = batch(runner, data / "pred", tmp_path / "out", "--jobs", "1", "--steps", "calibrate",
                   "--focal", "900", "--camera-height", "6.5", "--pitch", "20")
    assert result.exit_code == 0, result.stderr
    for rel in RELS:
        data_yaml = yaml.safe_load((tmp_path / "out" / rel / "camera.yaml").read_text())
        assert (data_yaml["focal_px"], data_yaml["height_m"]) == (pytest.approx(900.0), pytest.approx(6.5))
        assert data_yaml["pitch_deg"] == pytest.approx(20.0, abs=1e-6)
        assert data_yaml["fit"]["fixed"]["focal_px"] == "given"


def test_a_camera_file_replaces_every_sequence_s_calibration(data, tmp_path, runner):
    from _camera_gate import FINDINGS, implausible

    given = data / "gt" / "a" / "s1" / "camera.yaml"
    result = batch(runner, data / "pred", tmp_path / "out", "--jobs", "1", "--steps", "calibrate,align", "--camera", given)
    assert result.exit_code == 0, result.stderr
    camera = read_camera_yaml(given)[0]
    for rel in RELS:
        assert read_camera_yaml(tmp_path / "out" / rel / "camera.yaml")[0] == camera  # copied, not fitted
        assert open_sequence(tmp_path / "out" / rel / "aligned").camera == camera
    rows = json.loads((tmp_path / "out" / "batch_report.json").read_text())["rows"]
    assert {(r["camera"]["origin"], r["camera"]["file"]) for r in rows} == {("given", str(given.resolve()))}

    both = batch(runner, data / "pred", tmp_path / "x", "--camera", given, "--focal", "900")
    assert both.exit_code == 2 and "not both" in both.stderr
    bad = implausible(given, tmp_path / "bad.yaml")
    result = batch(runner, data / "pred", tmp_path / "out2", "--jobs", "1", "--steps", "align", "--camera", bad, "--json")
    assert result.exit_code == 1
    failed = json.loads(result.stdout)["failed"]
    assert len(failed) == 3 and all(f"{bad.resolve()}: implausible camera ({FINDINGS[0]}" in f["reason"] for f in failed)
