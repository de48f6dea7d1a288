"""Arguments of the wrong type, every public function: ``mrlib.__all__``'s functions,
``TrainingSet``'s constructors and ``mrlib.constraints``. Each argument in turn is given
an object of no kind the function takes (then text, a list, a bool where they are none of
what it takes), the others valid: the call raises an ``MrlibError`` naming the argument
and the value, before any work (nothing written), never a ``TypeError`` or
``AttributeError`` from inside."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

import mrlib
from mrlib import constraints as C
from mrlib.datasets.synthetic import synthetic_walk
from mrlib.errors import ArgumentError, MrlibError
from mrlib.model.config import ModelConfig, TrainConfig

TINY = TrainConfig(
    model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
    block_iterations=(1,),
    n_critic=1,
    checkpoint_every=0,
)


class Fixtures:
    """What the valid arguments are made of."""

    def __init__(self, root: Path):
        self.motion = synthetic_walk("walk_sad", seconds=3.0, fps=10.0)
        self.clip = mrlib.save_motion(self.motion, root / "clip.npz")
        data = mrlib.TrainingSet.from_motions([self.motion])
        self.checkpoint = mrlib.train(data, TINY, root / "run", progress=False).checkpoint
        self.model = mrlib.load_model(self.checkpoint)
        self.keyframes = [C.Keyframe.from_motion(self.motion, 0, 0)]


@pytest.fixture(scope="module")
def fx(tmp_path_factory) -> Fixtures:
    return Fixtures(tmp_path_factory.mktemp("bad_arguments"))


# function -> (valid keyword arguments, {argument: junk kinds it accepts, not swept})
TEXT, LIST, FLAG = "text", "list", "flag"
CASES = {
    "load_motion": (
        lambda f, out: dict(path=f.clip),
        {"path": {TEXT}, "fps": set(), "joint_map": {TEXT}, "body": set(),
         "up_axis": {TEXT}, "unit": {TEXT}, "person": set(), "label": {TEXT}},
    ),
    "save_motion": (
        lambda f, out: dict(motion=f.motion, path=out / "x.npz"),
        {"motion": set(), "path": {TEXT}, "body": set(), "bvh_unit": set(),
         "euler_order": set(), "overwrite": set()},
    ),
    "load_body_model": (
        lambda f, out: dict(),
        {"path": {TEXT}, "gender": set(), "num_betas": set(), "device": {TEXT}},
    ),
    "TrainingSet.from_motions": (
        lambda f, out: dict(motions=[f.motion]),
        {"motions": set(), "labels": set(), "fps": set(), "body": set()},
    ),
    "TrainingSet.from_files": (
        lambda f, out: dict(paths=[f.clip]),
        {"paths": set(), "labels": set(), "fps": set(), "body": set(), "joint_map": {TEXT}},
    ),
    "train": (
        lambda f, out: dict(data=None, config=None, out_dir=out / "run"),
        {"data": set(), "config": set(), "out_dir": {TEXT}, "resume": {TEXT},
         "body": set(), "progress": set(), "callback": set(), "overwrite": set()},
    ),
    "load_model": (
        lambda f, out: dict(path=f.checkpoint),
        {"path": {TEXT}, "device": {TEXT}},
    ),
    "generate": (
        lambda f, out: dict(model=f.model, condition="walk_sad"),
        {"model": set(), "condition": {TEXT}, "length": set(), "seed": set(), "num": set(),
         "sampler": set(), "levels": set(), "body": set()},
    ),
    "restyle": (
        lambda f, out: dict(model=f.model, motion=f.motion, label="walk_sad"),
        {"model": set(), "motion": {TEXT}, "label": {TEXT}, "level": set(), "keep": set(),
         "seed": set(), "align": set(), "sampler": set(), "body": set()},
    ),
    "evaluate_model": (
        lambda f, out: dict(model=f.model),
        {"model": set(), "baselines": set(), "name": {TEXT}, "contacts": set(),
         "settings": set(), "calibration": set(), "body": set(), "progress": set()},
    ),
    # mrlib.constraints
    "C.parse_path": (lambda f, out: dict(spec="line:2"), {"spec": {TEXT}}),
    "C.follow_path": (
        lambda f, out: dict(motion=f.motion, path="line:2"),
        {"motion": set(), "path": {TEXT}, "smooth_s": set(), "clean": set(), "body": set(),
         "jitter": set()},  # fmt: skip
    ),
    "C.generate_on_path": (
        lambda f, out: dict(model=f.model, path="line:2", condition="walk_sad"),
        {"model": set(), "path": {TEXT}, "condition": {TEXT}, "seconds": set(),
         "seed": set(), "sampler": set(), "body": set(), "max_seconds": set()},
    ),
    "C.natural_pace": (
        lambda f, out: dict(model=f.model, condition="walk_sad"),
        {"model": set(), "condition": {TEXT}, "seed": set(), "sampler": set()},
    ),
    "C.path_seconds": (
        lambda f, out: dict(model=f.model, path="line:2", condition="walk_sad"),
        {"model": set(), "path": {TEXT}, "condition": {TEXT}, "sampler": set()},
    ),
    "C.ground_track": (
        lambda f, out: dict(motion=f.motion),
        {"motion": set(), "body": set(), "smooth_s": set()},
    ),
    "C.path_error": (
        lambda f, out: dict(motion=f.motion, path="line:2"),
        {"motion": set(), "path": {TEXT}, "body": set()},
    ),
    "C.save_keyframes": (
        lambda f, out: dict(path=out / "k.npz", keyframes=f.keyframes),
        {"path": {TEXT}, "keyframes": {LIST}, "overwrite": set()},
    ),
    "C.load_keyframes": (lambda f, out: dict(path=out / "k.npz"), {"path": {TEXT}}),
    "C.align_to_keyframes": (
        lambda f, out: dict(motion=f.motion, keyframes=f.keyframes),
        {"motion": set(), "keyframes": {LIST}, "body": set()},
    ),
    "C.apply_keyframes": (
        lambda f, out: dict(motion=f.motion, keyframes=f.keyframes),
        {"motion": set(), "keyframes": {LIST}, "blend_s": set()},
    ),
    "C.keyframe_errors": (
        lambda f, out: dict(motion=f.motion, keyframes=f.keyframes),
        {"motion": set(), "keyframes": {LIST}},
    ),
    "C.keyframe_objective": (
        lambda f, out: dict(model=f.model, keyframes=f.keyframes, length=30),
        {"model": set(), "keyframes": {LIST}, "length": set(), "still": set(), "body": set()},
    ),
    "C.generate_with_keyframes": (
        lambda f, out: dict(model=f.model, keyframes=f.keyframes, length=30, condition=0),
        {"model": set(), "keyframes": {LIST}, "length": set(), "condition": {TEXT},
         "seed": set(), "sampler": set(), "fit": set(), "body": set()},
    ),
    "C.continue_motion": (
        lambda f, out: dict(model=f.model, prefix=f.motion, frames=10, condition=0),
        {"model": set(), "prefix": set(), "frames": set(), "condition": {TEXT},
         "seed": set(), "sampler": set(), "fit": set(), "body": set()},
    ),
    "C.part_joints": (lambda f, out: dict(part="upper"), {"part": {TEXT, LIST}}),
    "C.parse_parts": (lambda f, out: dict(spec="upper=walk_sad"), {"spec": {TEXT}}),
    "C.generate_parts": (
        lambda f, out: dict(model=f.model, parts={"upper": "walk_sad"}),
        {"model": set(), "parts": set(), "length": set(), "seed": set(), "num": set(),
         "sampler": set(), "sharpen": set(), "body": set()},
    ),
    "C.splice_parts": (
        lambda f, out: dict(parts={"upper": f.motion, "lower": f.motion}),
        {"parts": set(), "name": {TEXT}, "align": set(), "body": set()},
    ),
    "C.gait_phase": (lambda f, out: dict(motion=f.motion), {"motion": set(), "body": set()}),
    "C.phase_align": (
        lambda f, out: dict(source=f.motion, target=f.motion),
        {"source": set(), "target": set(), "body": set()},
    ),
    "C.arm_leg_coordination": (
        lambda f, out: dict(motion=f.motion),
        {"motion": set(), "body": set()},
    ),
    "C.part_fidelity": (
        lambda f, out: dict(motions=[f.motion], model=f.model, parts={"upper": "walk_sad"}),
        {"motions": set(), "model": set(), "parts": set(), "window": set()},
    ),
    "C.label_margin_objective": (
        lambda f, out: dict(model=f.model, parts={"upper": "walk_sad"}),
        {"model": set(), "parts": set(), "margin": set(), "window": set(), "push": set()},
    ),
    "C.generate_sharpened": (
        lambda f, out: dict(model=f.model, condition="walk_sad"),
        {"model": set(), "condition": {TEXT}, "parts": {LIST}, "length": set(),
         "seed": set(), "num": set(), "sampler": set(), "fit": set()},
    ),
    "C.generate_loop": (
        lambda f, out: dict(model=f.model, condition="walk_sad"),
        {"model": set(), "condition": {TEXT}, "length": set(), "seed": set(),
         "sampler": set(), "body": set()},
    ),
    "C.loop_seam": (lambda f, out: dict(motion=f.motion), {"motion": set(), "body": set()}),
    "C.tile_loop": (lambda f, out: dict(motion=f.motion, cycles=2), {"motion": set(), "cycles": set()}),
    "C.roll_loop": (lambda f, out: dict(motion=f.motion, start=1), {"motion": set(), "start": set()}),
}  # fmt: skip


def _function(name: str):
    if name.startswith("C."):
        return getattr(C, name[2:])
    if name.startswith("TrainingSet."):
        return getattr(mrlib.TrainingSet, name.split(".")[1])
    return getattr(mrlib, name)


class Junk:
    """An object of no kind any mrlib function takes."""

    def __repr__(self) -> str:
        return "<junk>"


JUNK = {"object": Junk(), TEXT: "1e3", LIST: [Junk()], FLAG: True}
SWEEP = [
    (fn, arg, kind)
    for fn, (_, args) in CASES.items()
    for arg, accepted in args.items()
    for kind in JUNK
    if kind not in accepted and not (kind == FLAG and arg not in ("length", "seed", "fps"))
]


@pytest.mark.parametrize(("fn", "arg", "kind"), SWEEP, ids=[f"{f}-{a}-{k}" for f, a, k in SWEEP])
def test_a_wrong_argument_is_an_mrlib_error_naming_it(fn, arg, kind, fx, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    make, _ = CASES[fn]
    kwargs = make(fx, tmp_path)
    if fn == "C.load_keyframes":
        C.save_keyframes(tmp_path / "k.npz", fx.keyframes)
    before = set(tmp_path.rglob("*"))
    kwargs[arg] = JUNK[kind]
    with pytest.raises(MrlibError) as info:
        _function(fn)(**kwargs)
    text = str(info.value)
    assert arg in text, text
    assert {"object": "<junk>", TEXT: "'1e3'", LIST: "<junk>", FLAG: "True"}[kind] in text.replace(
        "'1E3'", "'1e3'"
    ), text
    assert len(text.splitlines()) == 1, text
    assert set(tmp_path.rglob("*")) == before, "wrote files before refusing"


def test_the_sweep_covers_every_public_function():
    """Each public function of mrlib.__all__ and mrlib.constraints is in CASES (or has no
    arguments to sweep), and each of its arguments is swept (``**kwargs`` aside)."""
    public = [n for n in mrlib.__all__ if inspect.isfunction(getattr(mrlib, n))]
    public += ["TrainingSet.from_motions", "TrainingSet.from_files"]
    public += [f"C.{n}" for n in C.__all__ if inspect.isfunction(getattr(C, n))]
    missing = [n for n in public if n not in CASES and n not in ("get_preset",)]
    assert not missing
    for name, (_, args) in CASES.items():
        params = inspect.signature(_function(name)).parameters
        swept = {p for p, v in params.items() if v.kind is not v.VAR_KEYWORD}
        unchecked = swept - set(args) - {"method", "start"}
        assert not unchecked, f"{name}: {sorted(unchecked)} not swept"


@pytest.mark.parametrize(
    "call",
    [
        lambda f: mrlib.generate(),
        lambda f: mrlib.generate(f.model, bogus=1),
        lambda f: mrlib.load_motion(),
        lambda f: C.tile_loop(f.motion),
    ],
    ids=["missing model", "unknown keyword", "missing path", "missing cycles"],
)
def test_a_call_that_does_not_fit_the_signature(call, fx):
    with pytest.raises(ArgumentError, match=r"\(\): (missing a required|got an unexpected)"):
        call(fx)


def test_generate_with_a_checkpoint_path_says_how_to_load_it(fx):
    """``generate`` takes a loaded model, never a path (a loop of calls would read the
    file each time): the error is the line that loads it."""
    with pytest.raises(ArgumentError) as info:
        mrlib.generate(str(fx.checkpoint), "walk_sad")
    assert f"model = mrlib.load_model('{fx.checkpoint}')" in str(info.value)
    assert isinstance(info.value, TypeError)  # still a TypeError for code that catches one


# the classes of mrlib.__all__: their constructors and methods
CLASS_CASES = {
    "Motion(fps='30')": (lambda m: mrlib.Motion(m.poses, m.trans, fps="30"), "fps"),
    "Motion(betas='x')": (lambda m: mrlib.Motion(m.poses, m.trans, 10.0, betas="x"), "betas"),
    "Motion(label=3)": (lambda m: mrlib.Motion(m.poses, m.trans, 10.0, label=3), "label"),
    "Motion(meta=[])": (lambda m: mrlib.Motion(m.poses, m.trans, 10.0, meta=[]), "meta"),
    "motion.resample('30')": (lambda m: m.resample("30"), "fps"),
    "motion.resample(None)": (lambda m: m.resample(None), "fps"),
    "motion.slice('a')": (lambda m: m.slice("a"), "start"),
    "motion.slice(0, 2.5)": (lambda m: m.slice(0, 2.5), "stop"),
    "motion.at_frames('x')": (lambda m: m.at_frames("x"), "frame positions"),
    "TrainConfig(lr='x')": (lambda m: mrlib.TrainConfig(lr="x"), "TrainConfig.lr"),
    "TrainConfig(seed='1')": (lambda m: mrlib.TrainConfig(seed="1"), "TrainConfig.seed"),
    "TrainConfig(model=3)": (lambda m: mrlib.TrainConfig(model=3), "TrainConfig.model"),
    "TrainConfig(block_iterations='5')": (
        lambda m: mrlib.TrainConfig(block_iterations="5"),
        "block_iterations",
    ),
    "TrainConfig(n_critic=True)": (lambda m: mrlib.TrainConfig(n_critic=True), "n_critic"),
    "ModelConfig(num_levels=4.0)": (
        lambda m: mrlib.TrainConfig(model=mrlib.model.config.ModelConfig(num_levels=4.0)),
        "ModelConfig.num_levels",
    ),
    "Sampler(fine_noise='0.5')": (lambda m: mrlib.Sampler(fine_noise="0.5"), "fine_noise"),
    "Sampler(guidance=None)": (lambda m: mrlib.Sampler(guidance=None), "guidance"),
    "Sampler(fix_contacts='ik')": (lambda m: mrlib.Sampler(fix_contacts="ik"), "fix_contacts"),
    "Sampler(match_contact_rate=1)": (
        lambda m: mrlib.Sampler(match_contact_rate=1),
        "match_contact_rate",
    ),
    "Condition.label(None)": (lambda m: mrlib.Condition.label(None), "label"),
    "Condition.crossover(level='2')": (
        lambda m: mrlib.Condition.crossover("a", "b", "2"),
        "crossover level",
    ),
    "Condition.levels([('a', 1)])": (lambda m: mrlib.Condition.levels([("a", 1)]), "levels"),
    "Condition.blend(w='x')": (lambda m: mrlib.Condition.blend("a", "b", "x"), "blend weights"),
    "get_preset('x').replace(device=None)": (
        lambda m: mrlib.get_preset("demo").replace(device=None),
        "device",
    ),
}


@pytest.mark.parametrize("case", list(CLASS_CASES))
def test_the_classes_refuse_wrong_types(case, fx):
    call, name = CLASS_CASES[case]
    with pytest.raises(MrlibError, match=name) as info:
        call(fx.motion)
    assert len(str(info.value).splitlines()) == 1
