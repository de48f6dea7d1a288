"""Training and sampling on an accelerator: every trainer option that adds tensors of its
own (conditional critics of each band, the mismatch and detail terms, speech) runs on the
device, its checkpoint loads on the CPU, the device and CPU samplers agree, and an
interrupted run resumes there. The device is ``$MRLIB_TEST_DEVICE`` (default ``cuda``);
skipped where it is CUDA and none is present."""

import csv
import math
import os

import numpy as np
import pytest
import torch

from mrlib.datasets.synthetic import synthetic_walk
from mrlib.model.config import LossWeights, ModelConfig, TrainConfig
from mrlib.model.trained import load_model
from mrlib.sampling.conditions import Condition
from mrlib.sampling.generation import generate
from mrlib.sampling.sampler import Sampler
from mrlib.speech import (
    SpeechClip,
    SpeechMotionPair,
    SpeechTrainingSet,
    load_speech_model,
    speech_train,
)
from mrlib.training.data import TrainingSet
from mrlib.training.trainer import train

DEVICE = os.environ.get("MRLIB_TEST_DEVICE", "cuda")
pytestmark = pytest.mark.skipif(
    DEVICE == "cuda" and not torch.cuda.is_available(), reason="needs a CUDA device"
)

TINY = ModelConfig(num_levels=3, gen_hidden=(24, 24), disc_hidden=(24, 24))


@pytest.fixture(scope="module")
def body():
    from mrlib.representation.body import load_body_model

    return load_body_model()


@pytest.fixture(scope="module")
def walks():
    return [
        synthetic_walk(s, seconds=2.5, fps=10.0, seed=k)
        for k, s in enumerate(["walk_normal", "walk_happy", "walk_sad"])
    ]


def _finite_log(path) -> int:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    values = [float(v) for r in rows for k, v in r.items() if v not in ("", None)]
    assert values and all(math.isfinite(v) for v in values)
    return len(rows)


@pytest.fixture
def full_precision():
    """CUDA convolutions default to TF32 (about 3 significant digits); compare in FP32."""
    flags = torch.backends.cudnn.allow_tf32, torch.backends.cuda.matmul.allow_tf32
    torch.backends.cudnn.allow_tf32 = torch.backends.cuda.matmul.allow_tf32 = False
    yield
    torch.backends.cudnn.allow_tf32, torch.backends.cuda.matmul.allow_tf32 = flags


@pytest.mark.parametrize("band", ["full", "detail"])
def test_label_training_on_the_device_loads_and_samples_on_both(
    tmp_path, body, walks, band, full_precision
):
    model = ModelConfig(
        num_levels=3,
        gen_hidden=(24, 24),
        disc_hidden=(24, 24),
        critic_condition=True,
        critic_band=band,
    )
    cfg = TrainConfig(
        model=model,
        loss=LossWeights(mismatch=1.0, detail=1.0),
        block_iterations=(3, 2),
        n_critic=2,
        critic_mixed="label",
        checkpoint_every=2,
        log_every=1,
        device=DEVICE,
    )
    res = train(TrainingSet.from_motions(walks), cfg, tmp_path, body=body, progress=False)
    assert _finite_log(res.log) > 0
    on_gpu, on_cpu = load_model(res.checkpoint, DEVICE), load_model(res.checkpoint, "cpu")
    assert on_gpu.device.type == torch.device(DEVICE).type
    a = generate(on_gpu, Condition.crossover("walk_sad", "walk_happy", 1), seed=4)
    b = generate(on_cpu, Condition.crossover("walk_sad", "walk_happy", 1), seed=4)
    err = (torch.as_tensor(a.poses) - torch.as_tensor(b.poses)).abs().max().item()
    assert err < 1e-4, f"device and CPU samples differ by {err:.2e}"


def test_an_interrupted_run_resumes_on_the_device(tmp_path, body, walks):
    cfg = TrainConfig(
        model=TINY, block_iterations=(3, 2), n_critic=1, checkpoint_every=0, device=DEVICE
    )

    def stop(trainer, _losses):
        if trainer.block == 1:
            raise KeyboardInterrupt

    data = TrainingSet.from_motions(walks)
    first = train(data, cfg, tmp_path / "a", body=body, progress=False, callback=stop)
    assert first.interrupted and load_model(first.checkpoint).trained_levels == 2
    res = train(None, None, tmp_path / "b", resume=first.checkpoint, body=body, progress=False)
    assert not res.interrupted and load_model(res.checkpoint).trained_levels == 3


def test_speech_training_on_cuda(tmp_path, body, walks):
    g = torch.Generator().manual_seed(0)
    pairs = [
        SpeechMotionPair(
            f"pair{k}",
            torch.randn(m.num_frames * 5, 6, generator=g),  # 50 Hz features, 10 fps motion
            50.0,
            0.0125,
            m.num_frames / 10.0,
            None,
            motion=m.replace(contacts=None),
        )
        for k, m in enumerate(walks)
    ]
    extra = [SpeechClip("audio", torch.randn(150, 6, generator=g), 50.0, 0.0125, 3.0, None)]
    data = SpeechTrainingSet.from_clips(pairs, extra, fps=10.0, body=body)
    model = ModelConfig(
        num_levels=3,
        gen_hidden=(24,),
        disc_hidden=(24,),
        critic_condition=True,
        critic_band="detail",
        film_joints=(12, 15, 16, 17),
    )
    cfg = TrainConfig(
        model=model,
        loss=LossWeights(mismatch=1.0),
        block_iterations=(2, 2),
        n_critic=1,
        mix_prob=0.0,
        checkpoint_every=0,
        log_every=1,
        device=DEVICE,
    )
    res = speech_train(data, cfg, tmp_path, body=body, progress=False)
    assert _finite_log(res.log) > 0
    assert load_speech_model(res.checkpoint).model.trained_levels == 3


def test_the_noise_fits_run_on_the_device_as_on_the_cpu(tmp_path, full_precision):
    # the constraints' test-time fits (mrlib.sampling.constraints.optimise) build their targets on
    # the model's device, and the foot clean-up runs on a body model there: a part's label
    # sharpened, an in-between fitted to keyframes, a continued prefix, a path and the
    # clean-up give the CPU's motion (the label windows of 30 frames need 4 s clips at
    # 10 fps)
    from mrlib.representation.body import load_body_model
    from mrlib.sampling import constraints as C
    from mrlib.sampling.cleanup import cleanup_foot_contacts

    cpu_body, device_body = load_body_model(), load_body_model().to(DEVICE)
    walks = [
        synthetic_walk(s, seconds=4.0, fps=10.0, seed=k)
        for k, s in enumerate(["walk_normal", "walk_happy", "walk_sad"])
    ]
    cfg = TrainConfig(model=TINY, block_iterations=(3, 2), n_critic=1, checkpoint_every=0,
                      device=DEVICE)  # fmt: skip
    data = TrainingSet.from_motions(walks)
    res = train(data, cfg, tmp_path, body=device_body, progress=False)
    kfs = [C.Keyframe.from_motion(walks[0], 0, 0), C.Keyframe.from_motion(walks[1], -1, 29)]
    cases = {
        "sharpened": lambda m, b: C.generate_sharpened(m, "walk_sad", ("upper",), 40, seed=1,
                                                       fit=C.Sharpening(5)),
        "keyframes": lambda m, b: C.generate_with_keyframes(m, kfs, 30, "walk_happy", seed=2,
                                                            fit=C.KeyframeFit(steps=5), body=b),
        "continued": lambda m, b: C.continue_motion(m, walks[2], 10, "walk_sad", seed=3,
                                                    fit=C.NoiseFit(steps=5), body=b),
        "path": lambda m, b: C.generate_on_path(m, "circle:1", "walk_normal", seconds=3.0,
                                                seed=4, body=b),
        "clean-up": lambda m, b: cleanup_foot_contacts(
            generate(m, "walk_sad", seed=5, sampler=Sampler(fix_contacts=False)), b),
    }  # fmt: skip
    on_device, on_cpu = load_model(res.checkpoint, DEVICE), load_model(res.checkpoint, "cpu")
    for name, make in cases.items():
        a, b = make(on_device, device_body), make(on_cpu, cpu_body)
        assert np.isfinite(a.poses).all(), name
        err = np.abs(a.poses - b.poses).max()
        assert err < 1e-3, f"{name}: device and CPU differ by {err:.2e}"
