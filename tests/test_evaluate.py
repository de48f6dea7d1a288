"""Tests for mrlib.evaluation.evaluate: scoring, the protocol with its calibration rows, and its
outputs. Real-data tests use the Bandai Namco clips in MRLIB_DATA_DIR."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from test_calibration import turning_walk

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.evaluation import calibration as cal
from mrlib.evaluation import evaluate as ev
from mrlib.io.paths import default_data_dir
from mrlib.representation.motion import Motion
from mrlib.viz.plots import plot_evaluation

DATA_DIR = default_data_dir()
needs_data = pytest.mark.skipif(
    not (DATA_DIR / "data").is_dir(), reason="Bandai-Namco data not found (MRLIB_DATA_DIR)"
)


def noisy_crops(refs: dict[str, Motion], sigma: float = 0.01, log: list | None = None):
    """A stand-in generator: a random window of the reference played three times, with
    per-frame rotation noise."""

    def sample_fn(label: str, length: int, seed: int) -> Motion:
        if log is not None:
            log.append((label, length, seed))
        ref = refs[label]
        rng = np.random.default_rng(seed)
        loop = cal.play_twice(cal.play_twice(ref))  # 4 T frames
        start = int(rng.integers(0, ref.num_frames))
        m = loop.slice(start, start + length)
        noise = rng.normal(scale=sigma, size=m.poses.shape).astype(np.float32)
        return m.replace(poses=m.poses + noise, contacts=None, name=f"{label} seed {seed}")

    return sample_fn


# -- calibration motions ----------------------------------------------------------------------
def test_settings_validate_and_describe_the_protocol():
    s = ev.EvaluationSettings(num_samples=5)
    text = s.describe()
    for piece in ("eps = 2", "T_c = 30", "T_min = 30", "T_d = 15", "5 samples", "0.15 m/s", "1 cm"):
        assert piece in text
    with pytest.raises(MotionValueError, match="num_samples"):
        ev.EvaluationSettings(num_samples=0)
    with pytest.raises(MotionValueError, match="eps"):
        ev.EvaluationSettings(eps=-1.0)
    with pytest.raises(MotionValueError, match="feature_kind"):
        ev.EvaluationSettings(feature_kind="quat")
    with pytest.raises(MotionValueError, match="contact_features"):
        ev.EvaluationSettings(contact_features="no")
    paper = ev.EvaluationSettings(feature_kind="rotmat", contact_features=False).describe()
    assert "rotation matrices" in paper and "no contact labels" in paper


def test_the_papers_distance_leaves_the_contact_labels_out(body):
    """The same poses with every contact label flipped: no window within eps 2 with mrlib's
    features (each frame differs by sqrt(6) in its labels), every window with the paper's
    (rotation matrices only), whose figures match the metric computed by hand."""
    from mrlib.metrics import coverage
    from mrlib.metrics.windows import metric_features
    from mrlib.representation.contacts import foot_contacts

    ref = turning_walk(70)
    ref = ref.replace(contacts=foot_contacts(ref, body))
    flipped = ref.replace(contacts=1.0 - ref.contacts)
    kw = dict(
        body=body, label="a", all_references={"a": ref, "b": ref.replace(poses=ref.poses * 0.5)}
    )
    ours = ev.score_motions([flipped], ref, settings=ev.EvaluationSettings(num_samples=1), **kw)
    paper = ev.EvaluationSettings(num_samples=1, feature_kind="rotmat", contact_features=False)
    theirs = ev.score_motions([flipped], ref, settings=paper, **kw)
    assert ours["coverage_pct"] == 0.0
    assert theirs["coverage_pct"] == theirs["coverage_tight_pct"] == 100.0
    assert theirs["cond_fidelity_pct"] == 100.0
    by_hand = coverage(
        metric_features(flipped, "rotmat", False), metric_features(ref, "rotmat", False)
    )
    assert theirs["coverage_pct"] == pytest.approx(100.0 * by_hand)
    # a reference cache built for other features is not used for these settings
    cached = ev.score_motions(
        [flipped], ref, settings=paper, _cache=ev._ReferenceCache(body, "6d", True), **kw
    )
    assert cached["coverage_pct"] == theirs["coverage_pct"]

    class OtherBody:  # a cache built for another body is not used either
        def __getattr__(self, name):
            raise AssertionError("the cache of another body was used")

    other = ev._ReferenceCache(OtherBody(), "rotmat", False)
    again = ev.score_motions([flipped], ref, settings=paper, _cache=other, **kw)
    assert again["coverage_pct"] == theirs["coverage_pct"]


# -- the protocol on constructed motion ---------------------------------------------------------
def test_evaluate_with_extra_models_reconstruction_and_fixed_seeds(body, tmp_path):
    ref = turning_walk(70)
    refs = {"arc": ref}
    log: list = []
    kw = dict(
        settings=ev.EvaluationSettings(num_samples=3, seed=5),
        calibration=ev.CalibrationOptions(others=None),
        body=body,
        progress=False,
    )
    res = ev.evaluate(
        {"dummy": noisy_crops(refs, 0.01, log), "noisier": noisy_crops(refs, 0.1)},
        refs,
        reconstructions={"dummy": {"arc": ref}},
        **kw,
    )
    assert log == [("arc", 140, 5), ("arc", 140, 6), ("arc", 140, 7)]
    assert res.methods == ["dummy", "noisier", "calib: played twice", "calib: frozen first frame"]
    by = {r["method"]: r for r in res.rows}
    assert by["dummy"]["recon_error"] == 0.0
    assert math.isnan(by["noisier"]["recon_error"]) and math.isnan(by["dummy"]["cond_fidelity_pct"])
    assert by["dummy"]["samples"] == 3 and by["dummy"]["frames"] == 140
    # a real clip too short to score is left out, named (not called "generated")
    short = ref.slice(0, 20).replace(name="take_002")
    few = dict(kw, calibration=ev.CalibrationOptions(others={"arc": {"other take": short}}))
    notes = ev.evaluate({"dummy": noisy_crops(refs, 0.01)}, refs, **few).notes
    assert any("'other take' left out: take_002 has" in n for n in notes), notes
    # more noise: more jitter, more local diversity
    assert by["noisier"]["jerk_ratio"] > by["dummy"]["jerk_ratio"] > 1.0
    assert by["noisier"]["local_div"] > by["dummy"]["local_div"]
    assert by["calib: played twice"]["coverage_pct"] == 100.0
    assert by["calib: played twice"]["coverage_tight_pct"] == 100.0
    assert by["calib: frozen first frame"]["jerk"] == 0.0
    # the tight threshold never covers more than the loose one, and is a column of its own
    assert all(r["coverage_tight_pct"] <= r["coverage_pct"] for r in res.rows)
    assert "Coverage (tight eps) %" in res.to_markdown()
    from dataclasses import replace

    same = ev.EvaluationResult(res.rows, replace(res.settings, tight_eps=res.settings.eps))
    assert "Coverage (tight eps) %" not in same.to_markdown()  # no column repeating another
    # the same seeds give the same numbers
    again = ev.evaluate(
        {"dummy": noisy_crops(refs, 0.01)}, refs, reconstructions={"dummy": {"arc": ref}}, **kw
    )
    assert again.rows[0] == res.rows[0]
    md = res.to_markdown()
    assert "Recon. err." in md and "Cond. fid." not in md  # no column without values
    path = res.to_csv(tmp_path / "rows.csv")
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 and rows[1]["recon_error"] == "" and float(rows[0]["recon_error"]) == 0.0


def test_rows_far_less_in_contact_than_their_clip_are_noted(body):
    """Skating counts contact frames: samples of a model that never labels a contact, or
    a clip without labels whose feet slide (contacts where feet are slow: none), read
    0 % and are named in the notes; samples in contact as often as the clip are not."""
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.representation.contacts import foot_contacts

    w = synthetic_walk("walk_sad", seconds=3.0, fps=30.0, body=body)
    refs = {"walk": w.replace(contacts=foot_contacts(w, body))}
    crops = noisy_crops(refs, 0.0)

    def never(label, n, seed):
        m = crops(label, n, seed)
        return m.replace(contacts=np.zeros((m.num_frames, 6), np.float32))

    def dragged(label, n, seed):  # the whole body slid forward at 1 m/s more
        m = crops(label, n, seed)
        return m.replace(trans=m.trans + np.outer(np.arange(n) / m.fps, [0, 0, 1.0]))

    res = ev.evaluate(
        {"crops": crops, "never": never, "dragged": dragged}, refs,
        settings=ev.EvaluationSettings(num_samples=2), body=body, progress=False,
        calibration=ev.CalibrationOptions(others=None),
    )  # fmt: skip
    by = {r["method"]: r for r in res.rows}
    assert by["never"]["skate_pct"] == 0.0 and by["crops"]["contact_share"] > 0.2
    named = {n.split(",")[0] for n in res.notes}
    assert named == {"never", "dragged"}, res.notes
    assert any("(slow feet)" in n for n in res.notes) and "Notes:" in res.to_markdown()


def test_evaluate_validates_its_inputs(body):
    ref = turning_walk(70)
    kw = dict(
        settings=ev.EvaluationSettings(num_samples=1),
        calibration=ev.CalibrationOptions(enabled=False),
        body=body,
        progress=False,
    )
    with pytest.raises(MotionValueError, match="non-empty"):
        ev.evaluate({"m": noisy_crops({})}, {}, **kw)
    with pytest.raises(ClipTooShortError, match="at least 59"):
        ev.evaluate({"m": noisy_crops({"a": ref})}, {"a": ref.slice(0, 40)}, **kw)
    with pytest.raises(MotionValueError, match="expected a mrlib.Motion"):
        ev.evaluate({"m": lambda label, n, seed: np.zeros((n, 24, 3))}, {"a": ref}, **kw)
    with pytest.raises(MotionValueError, match="resample"):
        ev.evaluate({"m": lambda label, n, seed: ref.resample(15.0)}, {"a": ref}, **kw)
    with pytest.raises(MotionValueError, match="models must be a dict"):
        ev.evaluate(noisy_crops({"a": ref}), {"a": ref}, **kw)
    with pytest.raises(MotionValueError, match="not callable"):
        ev.evaluate({"m": 3}, {"a": ref}, **kw)


# -- real data ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def bandai(body):
    from mrlib.io import load_motion

    return {
        n: load_motion(DATA_DIR / "data" / f"dataset-1_{n}.bvh", body=body)
        for n in ("walk_happy_001", "bow_normal_001")
    }


@needs_data
def test_frozen_real_frame_has_zero_coverage_and_zero_jitter(bandai, body):
    ref = bandai["walk_happy_001"]
    row = ev.score_motions([cal.freeze_first_frame(ref)], ref, body=body)
    assert row["coverage_pct"] == 0.0
    assert row["jerk"] == 0.0 and row["jerk_ratio"] == 0.0
    assert row["global_div"] > 1.5 and row["local_div"] > 1.5


@needs_data
def test_calibration_rows_order_sensibly_on_a_real_walk(bandai, body):
    ref = bandai["walk_happy_001"]
    res = ev.evaluate(
        {}, {"walk_happy": ref}, body=body, progress=False,
        calibration=ev.CalibrationOptions(data_dir=DATA_DIR),
    )  # fmt: skip
    by = {r["method"].removeprefix("calib: "): r for r in res.rows}
    assert list(by) == list(ev.CALIBRATION_METHODS)
    twice, frozen = by["played twice"], by["frozen first frame"]
    style, content = by["other style"], by["different content"]
    # a copy: fully covered, no diversity (contact labels differ at the seam only)
    assert twice["coverage_pct"] == 100.0
    assert twice["global_div"] < 0.05 and twice["local_div"] < 0.1
    assert twice["w_root_speed"] < 0.01 and twice["skate_pct"] < 12.0
    # nothing moves
    assert frozen["coverage_pct"] == 0.0 and frozen["jerk"] == 0.0
    assert frozen["w_root_speed"] > 1.0
    # another walk covers a walk; a bow covers nothing and is the most different
    assert style["coverage_pct"] > 80.0 and 0.3 < style["global_div"] < 2.0
    assert content["coverage_pct"] < 10.0
    assert content["global_div"] > max(style["global_div"], frozen["global_div"], 2.5)
    assert content["local_div"] > max(style["local_div"], frozen["local_div"])
    assert twice["global_div"] < style["global_div"] < content["global_div"]
    assert by["other take"]["source"] == "dataset-1_walk_happy_002"


@needs_data
def test_evaluate_dummy_model_on_two_real_labels_writes_table_and_files(bandai, body, tmp_path):
    refs = {"walk_happy": bandai["walk_happy_001"], "bow_normal": bandai["bow_normal_001"]}
    log: list = []
    res = ev.evaluate(
        {"dummy": noisy_crops(refs, 0.003, log)},
        refs,
        ev.EvaluationSettings(num_samples=2),
        calibration=ev.CalibrationOptions(data_dir=DATA_DIR),
        body=body,
        progress=False,
    )
    T = {k: m.num_frames for k, m in refs.items()}
    assert log == [(k, 2 * T[k], s) for k in refs for s in (0, 1)]
    dummy = [r for r in res.rows if r["method"] == "dummy"]
    assert [r["sequence"] for r in dummy] == ["walk_happy", "bow_normal"]
    for r in dummy:
        assert r["coverage_pct"] > 80.0 and r["global_div"] < 1.0
        assert r["cond_fidelity_pct"] > 95.0  # multi-label: fidelity is filled
        assert r["jerk_ratio"] > 1.0  # the noise
    calib = {(r["method"], r["sequence"]) for r in res.rows if r["kind"] == "calibration"}
    assert ("calib: different content", "bow_normal") in calib  # a walk, for the bow
    summary = {d["method"]: d for d in res.summary()}
    cov = [r["coverage_pct"] for r in dummy]
    assert summary["dummy"]["coverage_pct_mean"] == pytest.approx(np.mean(cov))
    assert summary["dummy"]["coverage_pct_std"] == pytest.approx(np.std(cov))

    paths = res.save(tmp_path / "out")
    assert set(paths) == {"csv", "summary_csv", "markdown", "settings"}
    with paths["csv"].open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(res.rows) and list(rows[0])[:4] == [
        "method",
        "kind",
        "sequence",
        "source",
    ]
    md = paths["markdown"].read_text()
    assert "| dummy | walk_happy |" in md and "calib: played twice" in md
    assert "eps = 2" in md and "T_c = 30" in md and "T_min = 30" in md and "T_d = 15" in md
    assert "Cond. fid. %" in md
    png = tmp_path / "out" / "evaluation.png"
    plot_evaluation(res, png)
    assert png.stat().st_size > 20_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# -- evaluate_model: which output of a trained model is scored ---------------------------------
def test_evaluate_model_scores_cleaned_samples_by_default_with_the_raw_ones_beside(
    sad_wave_model, body
):
    from mrlib.sampling.generation import generate
    from mrlib.sampling.sampler import Sampler

    model = sad_wave_model  # clips of 40 and 36 frames: short windows
    settings = ev.EvaluationSettings(num_samples=1, coverage_window=10, tmin=10, local_window=5)
    off = ev.CalibrationOptions(enabled=False)
    res = ev.evaluate_model(
        model, {"base": model}, settings=settings, calibration=off, body=body, progress=False
    )
    # the default is "both", for the model and every baseline alike, each raw row after its own
    assert res.methods == ["ours", "ours (raw)", "base", "base (raw)"]
    refs = ev.model_references(model)
    for label, ref in refs.items():
        n = 2 * ref.num_frames
        cleaned = generate(model, label, length=n, seed=0)  # what mrlib.generate returns
        raw = generate(model, label, length=n, seed=0, sampler=Sampler(fix_contacts=False))
        assert not np.allclose(cleaned.trans, raw.trans)  # the clean-up moved something
        want = {
            kind: ev.score_motions([m], ref, settings=settings, body=body)
            for kind, m in (("clean", cleaned), ("raw", raw))
        }
        keys = ("skate_pct", "penetration_cm", "jerk_ratio", "local_div")
        assert any(want["clean"][k] != pytest.approx(want["raw"][k]) for k in keys)
        rows = {r["method"]: r for r in res.rows if r["sequence"] == label}
        for method, kind in (("ours", "clean"), ("ours (raw)", "raw"), ("base", "clean")):
            for key in keys:
                assert rows[method][key] == pytest.approx(want[kind][key]), (method, key)
        assert rows["ours"]["recon_error"] == rows["ours (raw)"]["recon_error"]
    # "raw" and "clean" score one output per method
    only_raw = ev.evaluate_model(
        model, {"base": model}, contacts="raw", settings=settings, calibration=off,
        body=body, progress=False,
    )  # fmt: skip
    assert only_raw.methods == ["ours", "base"]
    raw_rows = {(r["method"], r["sequence"]): r for r in only_raw.rows}
    both_rows = {(r["method"], r["sequence"]): r for r in res.rows}
    for label in refs:
        assert raw_rows[("base", label)]["skate_pct"] == pytest.approx(
            both_rows[("base (raw)", label)]["skate_pct"]
        )
    one = next(iter(refs))  # a baseline of one model per clip misses none
    with pytest.raises(MotionValueError, match="one model for each of"):
        ev.evaluate_model(model, {"base": {one: model}}, settings=settings, progress=False)
    with pytest.raises(MotionValueError, match="clash"):
        ev.evaluate_model(
            model, {"ours (raw)": model}, settings=settings, calibration=off, body=body,
            progress=False,
        )  # fmt: skip
