"""Speech-conditioned training and generation from audio (mrlib.speech.train, .sample).

The data are made here, without espeak-ng or the Bandai clips: syllable-like tone bursts
as speech and the synthetic gesture recipe of ``mrlib.speech.synthetic`` on the procedural
standing base, so every test runs anywhere in a few seconds.
"""

import dataclasses
import json

import numpy as np
import pytest
import soundfile
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.model.checkpoint import CheckpointError, load_checkpoint
from mrlib.model.config import ConfigError, LossWeights, ModelConfig, TrainConfig
from mrlib.model.generator import LevelGenerator
from mrlib.model.pyramid import PackedLevels, pyramid_lengths
from mrlib.representation.features import channel_joint
from mrlib.representation.skeleton import UPPER_BODY_JOINTS, graph_distances
from mrlib.sampling.sampler import Sampler
from mrlib.speech import (
    SpeechClip,
    SpeechFeatureExtractor,
    SpeechModelError,
    SpeechMotionPair,
    SpeechTrainer,
    SpeechTrainingSet,
    downsample_levels,
    evaluate_speech_sync,
    generate_from_audio,
    levels_to_residuals,
    load_speech_model,
    phrase_loudness,
    speech_conditions,
    speech_model_from_trainer,
    speech_paper,
    speech_train,
    speech_tutorial,
    standing_base,
    wrist_lift,
)
from mrlib.speech.gestures import apply_offsets, gesture_offsets, loop_motion
from mrlib.speech.train import residual_operators

SR = 16_000
FPS = 12.5  # half the paper's 25 fps: shorter sequences, same code
LOGMEL = SpeechFeatureExtractor(kind="logmel", n_mels=12, pitch=False)  # D = 13
TINY = ModelConfig(
    num_levels=3,
    gen_hidden=(24,),
    disc_hidden=(24,),
    neighbour_radius=1,
    film_joints=UPPER_BODY_JOINTS,
)


def tiny(**kw) -> TrainConfig:
    base = dict(
        model=TINY,
        block_size=2,
        block_iterations=(3, 2),
        n_critic=1,
        mix_prob=0.0,
        checkpoint_every=0,
        log_every=1,
        seed=5,
    )
    base.update(kw)
    return TrainConfig(**base)


@pytest.fixture(autouse=True)
def one_thread():
    """Tiny networks gain nothing from threads; on a busy 2-core machine OpenMP
    spin-waiting makes small ops much slower."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def bursts(seconds: float, seed: int, sr: int = SR) -> np.ndarray:
    """Speech-like audio ``(N,)``: voiced bursts of 0.1-0.35 s with gaps, random loudness."""
    rng = np.random.default_rng(seed)
    n = int(seconds * sr)
    wav = np.zeros(n, np.float32)
    t = 0.2
    while t < seconds - 0.4:
        dur = rng.uniform(0.1, 0.35)
        a, b = int(t * sr), int((t + dur) * sr)
        tt = np.arange(b - a) / sr
        f0 = rng.uniform(100, 220)
        tone = sum(np.sin(2 * np.pi * f0 * h * tt) / h for h in (1, 2, 3))
        wav[a:b] = rng.uniform(0.05, 0.4) * np.hanning(b - a) * tone
        t += dur + rng.choice([0.05, 0.1, 0.5])
    return wav


def pair(seconds: float, seed: int) -> SpeechMotionPair:
    wav = bursts(seconds, seed)
    T = int(round(seconds * FPS))
    base = standing_base(seconds=2.0, fps=FPS, seed=seed)
    motion = apply_offsets(loop_motion(base, T), gesture_offsets(wav, SR, FPS, T, seed))
    feats = LOGMEL(wav, SR)
    return SpeechMotionPair(
        f"pair{seed}",
        feats,
        50.0,
        0.0125,
        len(wav) / SR,
        None,
        motion=motion.replace(contacts=None),
    )


def clip(seconds: float, seed: int) -> SpeechClip:
    wav = bursts(seconds, seed)
    return SpeechClip(f"audio{seed}", LOGMEL(wav, SR), 50.0, 0.0125, len(wav) / SR, None)


@pytest.fixture(scope="module")
def body():
    from mrlib.representation.body import load_body_model

    return load_body_model()


@pytest.fixture(scope="module")
def pairs():
    return [pair(s, k) for k, s in enumerate((2.4, 3.0, 2.7))]


@pytest.fixture(scope="module")
def data(pairs, body):
    unpaired = [clip(s, 10 + k) for k, s in enumerate((3.5, 1.2))]  # one shorter than any pair
    return SpeechTrainingSet.from_clips(pairs, unpaired, LOGMEL.config, fps=FPS, body=body)


@pytest.fixture(scope="module")
def trained(data, body, tmp_path_factory):
    out = tmp_path_factory.mktemp("speech_run")
    res = speech_train(data, tiny(), out, body=body, progress=False)
    return res


# -- configuration and data -----------------------------------------------------------------
def test_presets_follow_the_paper():
    for c in (speech_paper(), speech_tutorial()):
        assert c.model.num_levels == 10 and c.model.scale_factor == pytest.approx(4 / 3)
        assert c.model.film_joints == UPPER_BODY_JOINTS and c.mix_prob == 0.0
        assert c.num_blocks == 5
    p = speech_paper()
    assert p.block_iterations == (15000, 25000, 25000, 25000, 25000) and p.lr == 1e-4
    assert (p.loss.adv, p.loss.con, p.loss.rec, p.loss.smooth) == (1.0, 5.0, 50.0, 5.0)
    assert not p.model.critic_condition and p.loss.mismatch == 0.0  # the paper's critics
    t = speech_tutorial()
    assert t.model.critic_condition and t.model.critic_band == "detail" and t.loss.mismatch > 0


@pytest.mark.parametrize("band", ["full", "detail"])
def test_conditional_critics_see_each_real_clip_with_its_own_speech(data, body, band, tmp_path):
    mc = dataclasses.replace(TINY, critic_condition=True, critic_band=band)
    tr = SpeechTrainer(data, tiny(model=mc), tmp_path, body=body, random_audio="paired")
    assert all(c.project.in_features == data.dim for c in tr.critics)
    assert all((c.detail is not None) == (band == "detail") for c in tr.critics)
    # the real clip in slot b is paired clip b mod N, scored with that clip's own speech
    for i in range(3):
        got = tr.batches.rand_layout.unpack(tr.signal.real_conds[i].transpose(1, 2), i)
        for b, k in enumerate(tr.batches.rand_clip.tolist()):
            own = speech_conditions(
                data.paired_features[k],
                50.0,
                FPS,
                tr.batches.lengths[k].tolist(),
                normalizer=data.normalizer,
                offset_s=0.0125,
            )
            assert torch.allclose(got[b].T, own[i])
    # a fake is scored with the speech that drove it where that speech is paired audio,
    # below its crossover level (critic_mixed="none") or at every level ("label"); never
    # with unpaired audio, which no real clip comes with
    for mixed in ("none", "label"):
        cfg = tiny(model=mc, mix_prob=0.5, critic_mixed=mixed)
        t = SpeechTrainer(data, cfg, tmp_path, body=body, random_audio="all")
        draws, sig, fake_layout = [], t.signal, t.batches.fake_layout
        draw_speech = sig.draw_speech
        sig.draw_speech = lambda layout: draws.append(draw_speech(layout)) or draws[-1]  # noqa: B023
        kinds = set()
        for _ in range(4):
            draw = sig.draw_random(fake_layout, 3)
            conds = draw.conds
            seen = sig.critic_conditions(draw, fake_layout)
            d = draws[-1]
            for i in range(3):
                got = fake_layout.unpack(seen[i].transpose(1, 2), i)
                full = fake_layout.unpack(conds[i].transpose(1, 2), i)
                for b in range(fake_layout.batch_size):
                    second = i >= int(d.cross[b])
                    src = d.source_b[b] if second else d.source[b]
                    heard = bool(src < data.num_paired) and (mixed == "label" or not second)
                    kinds.add(heard)
                    assert torch.equal(got[b], full[b] if heard else torch.zeros_like(full[b]))
        assert kinds == {True, False}
    # the speech term is trained, and the real clips' pairing enters the critic loss
    tr.start_block()
    before = [c.project.weight.clone() for c in tr.critics[:2]]
    swapped = SpeechTrainer(data, tiny(model=mc), tmp_path, body=body, random_audio="paired")
    swapped.signal.real_conds = [c.flip(1) for c in swapped.signal.real_conds]
    swapped.start_block()
    la, lb = tr.step(), swapped.step()
    assert all(
        not torch.equal(b, c.project.weight) for b, c in zip(before, tr.critics[:2], strict=True)
    )
    assert not torch.equal(la[0]["D"], lb[0]["D"])
    # the critics' speech projection survives a checkpoint round trip
    res = speech_train(
        data, tiny(model=mc), tmp_path / "run", body=body, progress=False, random_audio="all"
    )
    again = SpeechTrainer.from_checkpoint(res.checkpoint)
    saved = load_checkpoint(res.checkpoint)["critics"]
    assert torch.equal(again.critics[1].project.weight, saved["1.project.weight"])
    # a speech model's samples follow audio: it chooses no contact reading
    assert "contact_at_rate" not in load_checkpoint(res.checkpoint)


def test_random_audio_default_follows_the_critics(data, body, tmp_path):
    assert SpeechTrainer(data, tiny(), tmp_path, body=body).random_audio == "unpaired"
    mc = dataclasses.replace(TINY, critic_condition=True)
    assert SpeechTrainer(data, tiny(model=mc), tmp_path, body=body).random_audio == "paired"
    with pytest.warns(UserWarning, match="paired audio only"):
        SpeechTrainer(data, tiny(model=mc), tmp_path, body=body, random_audio="unpaired")
    alone = dataclasses.replace(data, unpaired_features=[], unpaired_frames=[], unpaired_names=[])
    assert SpeechTrainer(alone, tiny(), tmp_path, body=body).random_audio == "paired"


def test_speech_mismatch_is_each_clips_own_speech_out_of_step(data, body, tmp_path):
    from mrlib.model.config import LossWeights

    mc = dataclasses.replace(TINY, critic_condition=True, critic_band="detail")
    cfg = tiny(model=mc, loss=LossWeights(mismatch=1.0))
    tr = SpeechTrainer(data, cfg, tmp_path, body=body, random_audio="paired")
    for i in range(3):
        lay, sig = tr.batches.rand_layout, tr.signal
        own = lay.unpack(sig.real_conds[i].transpose(1, 2), i)
        wrong = lay.unpack(sig.mismatched_real_conditions(i).transpose(1, 2), i)
        for o, w in zip(own, wrong, strict=True):
            T = o.shape[1]
            shifts = [s for s in range(1, T) if torch.equal(o.roll(s, 1), w)]
            assert len(shifts) == 1 and T / 4 - 1 <= shifts[0] <= 3 * T / 4 + 1
    tr.start_block()
    assert all(torch.isfinite(tr.step()[i]["mis"]) for i in (0, 1))


def test_training_set_holds_paired_and_unpaired_audio(data, pairs, body):
    assert (data.num_paired, data.num_unpaired, data.dim) == (3, 2, 13)
    assert data.motion.labels == ["speech"] and data.motion.lengths == [30, 38, 34]
    assert data.unpaired_frames == [44, 15]
    every = torch.cat(data.paired_features + data.unpaired_features)
    assert torch.allclose(data.normalizer.mean, every.mean(0), atol=1e-4)
    finest, kinds = data.finest()
    assert [f.shape[0] for f in finest] == [30, 38, 34, 44, 15]
    assert kinds == ["paired"] * 3 + ["unpaired"] * 2
    with pytest.raises(MotionValueError, match="different feature sizes"):
        bad = dataclasses.replace(pairs[0], features=torch.randn(100, 7))
        SpeechTrainingSet.from_clips([bad, pairs[1]], [], LOGMEL.config, body=body)
    with pytest.raises(MotionValueError, match="needs unpaired audio"):
        SpeechTrainer(
            dataclasses.replace(data, unpaired_features=[], unpaired_frames=[]),
            tiny(),
            ".",
            random_audio="unpaired",
        )
    with pytest.raises(MotionValueError, match="random_audio"):
        SpeechTrainer(data, tiny(), ".", random_audio="some")
    with pytest.raises(ConfigError, match="no labels"):
        SpeechTrainer(data, tiny(loss=LossWeights(detail=1.0)), ".")


# -- conditions --------------------------------------------------------------------------------
def _window_naive(f: torch.Tensor, start: int, T: int) -> torch.Tensor:
    """Frames ``start..start+T-1`` of ``f``, played back and forth past its end."""
    n, out = f.shape[0], []
    for k in range(start, start + T):
        if n == 1:
            out.append(f[0])
            continue
        k %= 2 * (n - 1)
        out.append(f[k if k < n else 2 * (n - 1) - k])
    return torch.stack(out)


def test_residual_operators_equal_the_alignment_functions():
    lengths = pyramid_lengths(40, 4, 4 / 3)
    x = torch.randn(40, 5)
    ops = residual_operators(lengths)
    ref = levels_to_residuals(downsample_levels(x, lengths))
    for R, r in zip(ops, ref, strict=True):
        assert R.shape == (r.shape[0], 40)
        assert torch.allclose(R @ x, r, atol=1e-5)


@pytest.mark.parametrize("mix", [0.0, 1.0])
def test_random_conditions_match_the_naive_oracle(data, body, mix):
    tr = SpeechTrainer(data, tiny(mix_prob=mix), ".", body=body, random_audio="all")
    finest, _ = data.finest()
    layout = tr.batches.fake_layout
    for _ in range(3):
        draw = tr.signal.draw_speech(layout)
        conds = tr.signal.draw_conditions(draw, layout, 3)
        for b in range(layout.batch_size):
            lengths = layout.table[b].tolist()
            per = []
            for src, st in ((draw.source, draw.start), (draw.source_b, draw.start_b)):
                w = _window_naive(finest[int(src[b])], int(st[b]), lengths[-1])
                per.append(levels_to_residuals(downsample_levels(w, lengths)))
            for i in range(3):
                want = per[1][i] if i >= int(draw.cross[b]) else per[0][i]
                got = layout.unpack(conds[i].transpose(1, 2), i)[b].T
                assert torch.allclose(got, want, atol=1e-5)
    if mix == 1.0:
        assert (draw.cross < 3).all()
    else:
        assert (draw.cross == 3).all() and torch.equal(draw.source, draw.source_b)


def test_reconstruction_uses_only_paired_speech(data, body):
    tr = SpeechTrainer(data, tiny(), ".", body=body)
    rec, b = tr.signal.rec_conditions(3), tr.batches
    for k, f in enumerate(data.paired_features):
        own = speech_conditions(
            f, 50.0, FPS, b.lengths[k].tolist(), normalizer=data.normalizer, offset_s=0.0125
        )
        for i in range(3):
            assert torch.allclose(b.rec_layout.unpack(rec[i].transpose(1, 2), i)[k].T, own[i])
    # random generations: unpaired audio only (bank indices 3, 4), both clips get used
    seen = torch.cat([tr.signal.draw_speech(b.rand_layout).source for _ in range(20)])
    assert set(seen.tolist()) == {3, 4}
    paired_only = SpeechTrainer(data, tiny(), ".", body=body, random_audio="paired")
    assert set(paired_only.signal.draw_speech(paired_only.batches.rand_layout).source.tolist()) <= {
        0,
        1,
        2,
    }

    # other unpaired audio changes the adversarial terms, never the reconstruction term
    other = dataclasses.replace(
        data, unpaired_features=[f.flip(0) * 0.5 for f in data.unpaired_features]
    )
    tr2 = SpeechTrainer(other, tiny(), ".", body=body)
    for t in (tr, tr2):
        t.start_block()
    la, lb = tr.step(), tr2.step()
    for i in (0, 1):
        assert torch.equal(la[i]["rec"], lb[i]["rec"])
        assert not torch.equal(la[i]["adv"], lb[i]["adv"])


# -- training and checkpoints -----------------------------------------------------------------
def test_training_writes_a_safe_checkpoint_with_the_speech_normaliser(trained, data):
    state = torch.load(trained.checkpoint, weights_only=True)
    assert state["format"] == "mrlib-checkpoint" and state["progress"]["done"]
    sp = state["speech"]
    assert torch.equal(sp["normalizer"]["mean"], data.normalizer.mean)
    assert torch.equal(sp["normalizer"]["std"], data.normalizer.std)
    assert sp["dim"] == 13 and sp["random_audio"] == "unpaired" and sp["downsample"] == "area"
    assert '"kind": "logmel"' in sp["feature_config"] and '"n_mels": 12' in sp["feature_config"]
    assert state["cond_dim"] == 13 and state["labels"] == ["speech"]
    model = load_speech_model(trained.checkpoint)
    assert model.dim == 13 and model.num_levels == 3 and model.fps == FPS
    assert torch.equal(model.normalizer.std, data.normalizer.std)
    assert model.feature_config == LOGMEL.config
    with pytest.raises(CheckpointError, match="a label model, not a speech-conditioned one"):
        from mrlib.model.checkpoint import save_checkpoint

        plain = {k: v for k, v in load_checkpoint(trained.checkpoint).items() if k != "speech"}
        save_checkpoint(trained.checkpoint.parent / "plain.pt", plain)
        load_speech_model(trained.checkpoint.parent / "plain.pt")


def test_resume_continues_exactly(data, body, trained, tmp_path):
    def stop_at_2(trainer, losses):
        if trainer.block == 0 and trainer.iteration == 2:
            raise KeyboardInterrupt

    # a callback (step-level control) is the trainer's: SpeechTrainer.start(...).fit(...)
    res = SpeechTrainer.start(data, tiny(), tmp_path, body=body).fit(False, stop_at_2)
    assert res.interrupted
    res = speech_train(None, None, tmp_path, resume=res.checkpoint, body=body, progress=False)
    assert not res.interrupted
    a = load_checkpoint(trained.checkpoint)["generator"]
    b = load_checkpoint(res.checkpoint)["generator"]
    assert all(torch.equal(a[k], b[k]) for k in a)


# -- generation --------------------------------------------------------------------------------
def test_generate_from_audio_has_the_audio_duration(trained, tmp_path):
    model = load_speech_model(trained.checkpoint)
    for seconds in (2.0, 3.3, 4.1):
        wav = bursts(seconds, 7)
        m = generate_from_audio(model, wav, seed=0, sr=SR)
        assert m.num_frames == round(seconds * FPS) and m.fps == FPS and m.label == "speech"
    path = tmp_path / "talk.wav"
    soundfile.write(str(path), bursts(3.0, 8)[::1], SR)
    a = generate_from_audio(model, path, seed=3)
    b = generate_from_audio(trained.checkpoint, path, seed=3)  # a checkpoint path works too
    assert a.num_frames == round(3.0 * FPS) and a.meta["audio"] == "talk"
    assert np.array_equal(a.poses, b.poses)
    c = generate_from_audio(model, path, seed=4)
    assert not np.allclose(a.poses, c.poses)
    # a sample does not depend on the batch (the raw output: the foot clean-up turns on
    # contact labels thresholded at 0.5, which float rounding can tip)
    unplanted = Sampler(fix_contacts=False)
    raw = generate_from_audio(model, path, seed=3, sampler=unplanted)
    many = generate_from_audio(model, path, seed=3, num=2, sampler=unplanted)
    assert isinstance(many, list) and len(many) == 2
    assert np.allclose(many[0].poses, raw.poses, atol=1e-5)
    one, levels = generate_from_audio(model, path, seed=3, sampler=unplanted, levels=True)
    assert np.array_equal(one.poses, raw.poses)
    assert [lv.num_frames for lv in levels] == pyramid_lengths(38, 3, 4 / 3)
    pairs = generate_from_audio(model, path, seed=3, sampler=unplanted, num=1, levels=True)
    assert isinstance(pairs, list) and np.array_equal(pairs[0][1][0].poses, levels[0].poses)
    quiet = generate_from_audio(model, path, seed=3, sampler=Sampler(0.0, fix_contacts=False))
    assert np.abs(quiet.poses - raw.poses).max() > 1e-4  # the fine noise reaches the output
    with pytest.raises(MotionValueError, match="guidance"):
        generate_from_audio(model, path, sampler=Sampler(guidance=0.5))
    with pytest.raises(ClipTooShortError):
        generate_from_audio(model, bursts(0.3, 1), sr=SR)  # 4 frames: too few for 3 levels
    with pytest.raises(MotionValueError, match="sr="):
        generate_from_audio(model, bursts(2.0, 1))


def test_audio_drives_the_motion_and_the_control_is_computed(trained, body):
    model = load_speech_model(trained.checkpoint)
    a = generate_from_audio(model, bursts(3.0, 1), seed=0, sr=SR)
    b = generate_from_audio(model, bursts(3.0, 2), seed=0, sr=SR)
    assert not np.allclose(a.poses[:, 16:22], b.poses[:, 16:22])  # same noise, other speech
    utts = [(bursts(3.0, s), SR) for s in (1, 2)]
    res = evaluate_speech_sync(model, utts, seeds=(0,), body=body)
    keys = {f"{k}_{w}" for k in res.KEYS for w in ("model", "shuffled")}
    assert set(res.KEYS) == {"r", "beat", "lift", "pause", "speed"}
    assert len(res.rows) == 2 and set(res.summary()) == keys
    assert all(-1 <= r["lift_model"] <= 1 and 0 <= r["beat_shuffled"] <= 1 for r in res.rows)
    assert all(r["speed_model"] > 0 for r in res.rows)
    assert "other utterance" in res.to_markdown() and "paired" in res.to_markdown()
    mean, se, wins, n = res.paired("r")
    d = [r["r_model"] - r["r_shuffled"] for r in res.rows]
    assert n == 2 and wins == sum(x > 0 for x in d) and mean == pytest.approx(np.mean(d))
    assert se == pytest.approx(np.std(d, ddof=1) / np.sqrt(2))
    # a reference motion is scored with its own audio and with the other utterance's
    ref = generate_from_audio(model, bursts(3.0, 1), seed=5, sr=SR)
    res = evaluate_speech_sync(model, utts, seeds=(0,), body=body, references=[ref, None])
    assert {"lift_data", "lift_data_other"} <= set(res.rows[0]) and "lift_data" not in res.rows[1]
    assert res.rows[0]["speed_data"] == res.rows[0]["speed_data_other"]  # same motion
    assert res.rows[0]["lift_data"] != res.rows[0]["lift_data_other"]  # other audio
    assert "reference motion, other utterance's audio" in res.to_markdown()


def test_phrase_loudness_and_wrist_lift(body):
    wav = np.zeros(3 * SR, np.float32)
    wav[SR : 2 * SR] = 0.3 * np.sin(2 * np.pi * 150 * np.arange(SR) / SR)  # 1 s of sound
    e = phrase_loudness(wav, SR, 25.0, 75)
    assert e.shape == (75,) and 0 <= e.min() and e.max() <= 1
    # a 1 s plateau of 1 under a Gaussian of sigma 0.5 s: P(|Z| < 1) = 0.683 at its centre
    assert abs(e[37] - 0.683) < 0.05 and e[0] < 0.05 and e[74] < 0.05
    T = 20
    m = loop_motion(standing_base(seconds=1.0, fps=25.0), T)
    lift = np.linspace(0, 1.2, T)[:, None] * np.array([[-1.0, 0, 0]])  # shoulder flexion
    up = apply_offsets(m, {"left_shoulder": lift, "right_shoulder": lift})
    h0, h1 = wrist_lift(m, body), wrist_lift(up, body)
    assert h0.shape == (T,) and h0.max() < 0  # hanging arms: wrists below the pelvis
    assert abs(h1[0] - h0[0]) < 1e-6 and h1[-1] - h0[-1] > 0.3


def test_film_modulates_only_the_upper_body():
    """What is true: FiLM changes upper-body channels only; a level's skeleton convs
    (here 2 layers of radius 1) then carry the change at most 2 joints further, so after
    k levels joints more than 2k hops from the upper body are exactly unchanged."""
    torch.manual_seed(0)
    cfg = dataclasses.replace(TINY, num_levels=3)
    level = LevelGenerator(cfg, cond_dim=13)
    with torch.no_grad():  # an untrained FiLM is near identity; make it matter
        level.film.to_gamma.weight.normal_()
        level.film.to_delta.weight.normal_()
    owner = channel_joint()
    upper = np.isin(owner, UPPER_BODY_JOINTS)
    u = torch.randn(1, 153, 20)
    c1, c2 = torch.randn(1, 20, 13), torch.randn(1, 20, 13)
    with torch.no_grad():
        diff = (level.film(u, c1) - level.film(u, c2)).abs().amax((0, 2)).numpy()
    assert (diff[~upper] == 0).all() and (diff[upper] > 0).all()

    from mrlib.model.generator import MultiResGenerator

    gen = MultiResGenerator(cfg, cond_dim=13)
    with torch.no_grad():
        for lv in gen.levels:
            lv.film.to_gamma.weight.normal_()
            lv.film.to_delta.weight.normal_()
    lengths = [12, 16, 21]
    layout = PackedLevels.from_table(torch.tensor([lengths]), gap=4)
    noises = [torch.randn(1, 1, s) for s in layout.sizes]
    conds1 = [torch.randn(1, s, 13) for s in layout.sizes]
    conds2 = [torch.randn(1, s, 13) for s in layout.sizes]
    hops = graph_distances()[:, list(UPPER_BODY_JOINTS)].min(1)[owner]  # (C,) hops to upper body
    changed = {}
    for k in (1, 2, 3):
        with torch.no_grad():
            y1 = gen.run(layout, noises, conds1, 0, k)
            y2 = gen.run(layout, noises, conds2, 0, k)
        changed[k] = (y1 - y2)[..., : lengths[k - 1]].abs().amax((0, 2)).numpy() > 0
        assert not changed[k][hops > 2 * k].any()
        assert changed[k][hops <= 2 * k].all()
    knees, ankles, feet = (np.isin(owner, j) for j in ((4, 5), (7, 8), (10, 11)))
    assert not changed[1][knees].any() and changed[2][ankles].all() and not changed[2][feet].any()
    assert changed[3].all()  # three levels reach every joint: the legs do follow the speech


def test_speech_model_from_trainer_and_wrong_features(data, body, trained):
    tr = SpeechTrainer(data, tiny(), ".", body=body)
    model = speech_model_from_trainer(tr)
    assert model.dim == 13 and model.model.trained_levels == 0
    model = load_speech_model(trained.checkpoint)
    model._extractor = SpeechFeatureExtractor(kind="logmel", n_mels=20)
    with pytest.raises(MotionValueError, match="trained on 13"):
        generate_from_audio(model, bursts(3.0, 1), sr=SR)


def test_wavlm_features_plumbing(tmp_path, body):
    """WavLM end to end with a tiny random model (plumbing only, not its quality)."""
    from transformers import WavLMConfig, WavLMModel

    torch.manual_seed(0)
    cfg = WavLMConfig(
        hidden_size=16,
        num_hidden_layers=1,
        num_attention_heads=2,
        intermediate_size=32,
        conv_dim=(8,) * 7,
        num_conv_pos_embeddings=16,
        num_conv_pos_embedding_groups=2,
        num_buckets=32,
        max_bucket_distance=100,
    )
    WavLMModel(cfg).save_pretrained(tmp_path / "wavlm")
    ex = SpeechFeatureExtractor(kind="wavlm", wavlm_path=str(tmp_path / "wavlm"), layer=1)
    ps = []
    for k, s in enumerate((2.4, 3.0)):
        p = pair(s, k)
        ps.append(dataclasses.replace(p, features=ex(bursts(s, k), SR)))
    un = [SpeechClip("u", ex(bursts(3.0, 9), SR), 50.0, 0.0125, 3.0, None)]
    data = SpeechTrainingSet.from_clips(ps, un, ex.config, fps=FPS, body=body)
    assert data.dim == 16
    res = speech_train(
        data, tiny(block_iterations=(1, 1)), tmp_path / "run", body=body, progress=False
    )
    model = load_speech_model(res.checkpoint)
    assert model.feature_config.kind == "wavlm" and model.dim == 16
    m = generate_from_audio(model, bursts(2.6, 3), seed=0, sr=SR)
    assert m.num_frames == round(2.6 * FPS)
    # the weights moved (the run copied to another machine): $MRLIB_WAVLM_PATH finds
    # them, as the error says; wavlm_path= and mrlib sample --wavlm name them
    (tmp_path / "wavlm").rename(tmp_path / "moved")
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("MRLIB_WAVLM_PATH", raising=False)
        with pytest.raises(SpeechModelError, match="MRLIB_WAVLM_PATH"):
            generate_from_audio(load_speech_model(res.checkpoint), bursts(2.6, 3), seed=0, sr=SR)
        mp.setenv("MRLIB_WAVLM_PATH", str(tmp_path / "moved"))
        again = generate_from_audio(
            load_speech_model(res.checkpoint), bursts(2.6, 3), seed=0, sr=SR
        )
        assert np.allclose(again.poses, m.poses, atol=1e-5)
    named = load_speech_model(res.checkpoint, wavlm_path=tmp_path / "moved")
    assert named.feature_config.wavlm_path == str(tmp_path / "moved")


def test_cli_sample_audio(trained, tmp_path, capsys):
    from mrlib.app.cli import main
    from mrlib.io import load_motion

    wav = tmp_path / "talk.wav"
    soundfile.write(str(wav), bursts(2.8, 4), 22_050)  # read as 2.03 s, resampled to 16 kHz
    out = tmp_path / "out"
    args = ["sample", str(trained.checkpoint), "--audio", str(wav), "--out", str(out)]
    assert main(args + ["--num", "2"]) == 0
    m = load_motion(out / "talk_seed0_1.npz")
    assert m.num_frames == round(len(bursts(2.8, 4)) / 22_050 * FPS)
    assert (out / "talk_seed0_0.bvh").is_file()
    assert main(["sample", str(trained.checkpoint), "--out", str(out)]) == 1
    assert "speech-conditioned model: pass --audio" in capsys.readouterr().err
    assert main(args + ["--seconds", "3"]) == 1


def test_cli_train_speech_from_folders(tmp_path, capsys):
    from mrlib.app.cli import main
    from mrlib.io import save_motion

    paired, unpaired = tmp_path / "paired", tmp_path / "unpaired"
    paired.mkdir()
    unpaired.mkdir()
    for k in range(2):
        p = pair(3.2, 20 + k)
        soundfile.write(str(paired / f"talk{k}.wav"), bursts(3.2, 20 + k), SR)
        save_motion(p.motion, paired / f"talk{k}.npz")
    soundfile.write(str(unpaired / "extra.wav"), bursts(4.0, 30), SR)
    out = tmp_path / "run"
    args = ["train-speech", str(paired), "--unpaired", str(unpaired), "--iterations", "1"]
    assert main(args + ["--out", str(out), "--no-progress"]) == 0
    state = load_checkpoint(out / "checkpoint.pt")
    assert state["speech"]["random_audio"] == "paired"  # the tutorial's critics hear speech
    assert json.loads(state["speech"]["feature_config"])["kind"] == "logmel"
    assert "done" in capsys.readouterr().out
    more = ["--random-audio", "all", "--out", str(tmp_path / "all"), "--no-progress"]
    assert main(args + more) == 0
    assert load_checkpoint(tmp_path / "all" / "checkpoint.pt")["speech"]["random_audio"] == "all"
    assert main(["train-speech", "--out", str(out)]) == 1  # neither folder nor --resume
    # a resumed run keeps its config: an option that would change it is refused, not dropped
    capsys.readouterr()
    resume = ["train-speech", "--resume", str(out / "checkpoint.pt"), "--out", str(out)]
    assert main(resume + ["--iterations", "5", "--fps", "30"]) == 1
    assert "--iterations, --fps cannot change it" in capsys.readouterr().err
    assert main(resume + ["--device", "cpu", "--no-progress"]) == 0
    assert main(args[:2] + ["--iterations", "1,2", "--out", str(out)]) == 1  # 5 blocks
