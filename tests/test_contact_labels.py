"""Contact labels at the label's contact rate (``mrlib.sampling.contact_labels``,
``Sampler.match_contact_rate``): how many frames are labelled, that confident outputs
are kept, and that generation uses them on the same draw."""

import dataclasses

import numpy as np
import pytest
import torch

from mrlib.errors import MotionValueError
from mrlib.sampling.conditions import Condition
from mrlib.sampling.contact_labels import (
    CONTACT_BAND,
    condition_contact_rates,
    label_contact_rates,
    rate_matched_contacts,
)
from mrlib.sampling.generation import generate, label_inputs, sample_ranked
from mrlib.sampling.sampler import Sampler, raw_sampler


@pytest.fixture(scope="module")
def model(normal_sad_model):
    """A plumbing model (two iterations per block): its samples mean nothing."""
    return normal_sad_model


def test_each_vertex_is_in_contact_on_its_rate_of_frames():
    rng = np.random.default_rng(0)
    raw = rng.uniform(0.2, 0.8, size=(3, 200, 6))  # unsure everywhere: the rate decides
    rates = np.array([0.1, 0.25, 0.4, 0.5, 0.6, 0.75])
    c = rate_matched_contacts(raw, rates)
    assert c.shape == raw.shape and set(np.unique(c)) <= {0.0, 1.0}
    np.testing.assert_allclose(c.mean(1), np.broadcast_to(rates, (3, 6)), atol=1 / 200)
    # the frames of highest output are the ones labelled
    for b in range(3):
        for j in range(6):
            on, off = raw[b, c[b, :, j] == 1, j], raw[b, c[b, :, j] == 0, j]
            assert on.min() > off.max()


def test_confident_outputs_are_not_overruled_to_reach_a_rate():
    lo, hi = CONTACT_BAND
    raw = np.full((1, 100, 6), hi + 0.05)
    raw[0, :50, 3:] = lo - 0.05  # half the frames surely not in contact on three vertices
    c = rate_matched_contacts(raw, np.full(6, 0.2))
    assert c[0, :, :3].all()  # all sure contacts, though the rate asks for 20 %
    np.testing.assert_array_equal(c[0, :50, 3:], 0)
    c = rate_matched_contacts(raw, np.full(6, 0.9))
    np.testing.assert_array_equal(c[0, :50, 3:], 0)  # the rate asks for 90 %: still none


def test_bad_shapes_are_refused():
    with pytest.raises(MotionValueError, match="rates"):
        rate_matched_contacts(np.zeros((2, 10, 6)), np.zeros(5))
    with pytest.raises(MotionValueError, match="outputs"):
        rate_matched_contacts(np.zeros((10, 6)), np.zeros(6))


def test_a_labels_rate_is_its_training_clips_share_of_contact_frames(model):
    rates = label_contact_rates(model)
    assert rates.shape == (len(model.labels), 6)
    for k in range(len(model.labels)):
        clips = [x for x, lab in zip(model.features, model.clip_labels, strict=True) if lab == k]
        want = np.concatenate([np.asarray(x[:, -6:]) > 0.5 for x in clips]).mean(0)
        np.testing.assert_allclose(rates[k], want)
    W = Condition.blend("walk_normal", "walk_sad", 0.25).weights(model)
    mixed = condition_contact_rates(model, W)
    i, j = model.labels.index("walk_normal"), model.labels.index("walk_sad")
    np.testing.assert_allclose(mixed, 0.75 * rates[i] + 0.25 * rates[j], atol=1e-6)


def test_generate_labels_the_same_draw_at_the_rate(model):
    kw = dict(length=60, seed=4, num=2)
    plain = generate(model, "walk_sad", sampler=raw_sampler(), **kw)
    rate = Sampler(fix_contacts=False, candidates=1, match_contact_rate=True)
    matched = generate(model, "walk_sad", sampler=rate, **kw)
    W = Condition.label("walk_sad").weights(model)
    lengths, amp, conds = label_inputs(model, W, 60, raw_sampler())
    out = sample_ranked(model, conds, lengths, amp, 4, 2, 1)[-1].transpose(1, 2)
    raw = model.normalizer.denormalize(out)[..., -6:]
    want = rate_matched_contacts(raw, condition_contact_rates(model, W))
    for b in range(2):
        np.testing.assert_array_equal(plain[b].poses, matched[b].poses)
        np.testing.assert_array_equal(plain[b].contacts, (raw[b] > 0.5).float().numpy())
        np.testing.assert_array_equal(matched[b].contacts, want[b])
        assert matched[b].meta["sampler"]["match_contact_rate"] is True
    assert plain[0].meta["sampler"]["match_contact_rate"] is False
    assert torch.is_tensor(raw)


def test_constrained_samples_read_their_labels_at_the_rate(model, monkeypatch, body):
    """Paths, keyframes, continuations, loops and sharpened body parts label their
    contacts at the condition's rate when the sampler asks, and cut at 0.5 when not."""
    import mrlib.sampling.contact_labels as cl
    import mrlib.sampling.generation as gen
    from mrlib.sampling import constraints as C

    calls, real = [], cl.output_contacts

    def spy(m, x, W):
        calls.append((W.clone(), real(m, x, W)))
        return calls[-1][1]

    monkeypatch.setattr(cl, "output_contacts", spy)
    monkeypatch.setattr(gen, "output_contacts", spy)
    walk = generate(model, "walk_sad", length=30, seed=1, sampler=raw_sampler())
    kfs = [C.Keyframe.from_motion(walk, 0, 0)]

    def draw(sampler):
        return {
            "keyframes": C.generate_with_keyframes(
                model, kfs, 30, "walk_sad", seed=0, sampler=sampler,
                fit=C.KeyframeFit(steps=1), body=body,
            ),
            "continuation": C.continue_motion(
                model, walk.slice(0, 10), 20, "walk_sad", seed=0, sampler=sampler,
                fit=C.NoiseFit(steps=1), body=body,
            ),
            "loop": C.generate_loop(model, "walk_sad", 40, seed=1, start="sample",
                                    sampler=sampler, body=body),
            "path": C.generate_on_path(model, "circle:2", "walk_sad", seconds=3.0, seed=0,
                                       sampler=sampler, body=body),
            "sharpened": C.generate_sharpened(model, "walk_sad", ("upper",), 30, seed=0,
                                              sampler=sampler, fit=C.Sharpening(1)),
        }  # fmt: skip

    draw(raw_sampler())
    assert calls == []  # the paper's cut
    made = draw(Sampler(fix_contacts=False, candidates=1, match_contact_rate=True))
    W = Condition.label("walk_sad").weights(model)
    assert len(calls) == len(made)
    assert all(torch.equal(w, W) for w, _ in calls)
    np.testing.assert_array_equal(made["loop"].contacts, calls[2][1][0])
    np.testing.assert_array_equal(made["sharpened"].contacts, calls[4][1][0])
    assert made["sharpened"].meta["sampler"]["match_contact_rate"] is True


def test_a_sampler_setting_overrules_the_models_choice(model, monkeypatch):
    from mrlib.sampling.contact_labels import reads_at_rate

    W = Condition.blend("walk_normal", "walk_sad", 0.25).weights(model)  # mostly normal
    monkeypatch.setattr(model, "contact_at_rate", ("walk_normal",))
    assert reads_at_rate(model, Sampler(), W) is True
    assert reads_at_rate(model, Sampler(match_contact_rate=False), W) is False
    W_sad = Condition.label("walk_sad").weights(model)
    assert reads_at_rate(model, Sampler(), W_sad) is False
    assert reads_at_rate(model, Sampler(match_contact_rate=True), W_sad) is True
    monkeypatch.setattr(model, "contact_at_rate", None)  # a checkpoint without a choice
    assert reads_at_rate(model, Sampler(), W) is False
    # generate follows the choice, and records what it did
    monkeypatch.setattr(model, "contact_at_rate", ("walk_sad",))
    chose = generate(model, "walk_sad", length=60, seed=4, sampler=Sampler(fix_contacts=False))
    forced = Sampler(fix_contacts=False, match_contact_rate=True)
    rate = generate(model, "walk_sad", length=60, seed=4, sampler=forced)
    np.testing.assert_array_equal(chose.contacts, rate.contacts)
    assert chose.meta["sampler"]["match_contact_rate"] is True


def test_the_rate_is_chosen_where_it_wins_by_the_margin(model, monkeypatch):
    """The choice compares the two readings of the same draws by their fidelity to the
    training clips: a label is read at its rate only where that wins by the margin."""
    import mrlib.sampling.contact_choice as cc

    gains = {"walk_normal": 2 * cc.CHOICE_MARGIN, "walk_sad": cc.CHOICE_MARGIN / 2}
    seen = []

    read = []

    def fidelity(motions, refs, window):
        label, rated = motions[0].label, len(seen) % 2 == 1
        seen.append((label, rated, sorted(refs)))
        read.append(np.stack([m.contacts for m in motions]))
        return 0.5 + (gains[label] if rated else 0.0)

    monkeypatch.setattr(cc, "condition_fidelity", fidelity)
    assert cc.choose_contact_reading(model, num=2) == ("walk_normal",)
    for i, label in enumerate(("walk_normal", "walk_sad")):  # one draw, read both ways
        cut, rated = read[2 * i], read[2 * i + 1]
        W = Condition.label(label).weights(model)
        lengths, amp, conds = label_inputs(model, W, cut.shape[1], Sampler())
        out = sample_ranked(model, conds, lengths, amp, cc.CHOICE_SEED, 2, Sampler().candidates)
        raw = model.normalizer.denormalize(out[-1].transpose(1, 2))[..., -6:]
        np.testing.assert_array_equal(cut, (raw > 0.5).float().numpy())
        np.testing.assert_array_equal(rated, cc.output_contacts(model, out[-1], W))
    assert [s[:2] for s in seen] == [
        ("walk_normal", False),
        ("walk_normal", True),
        ("walk_sad", False),
        ("walk_sad", True),
    ]
    assert all(s[2] == ["walk_normal", "walk_sad"] for s in seen)  # every label's clips


def test_a_finished_run_records_its_choice_in_the_checkpoint(tmp_path, monkeypatch):
    """Training ends by choosing (once: a resumed finished run keeps its choice); a
    checkpoint written before models chose loads without one and reads at 0.5; a run
    reused from the cache chooses when loaded."""
    import mrlib.sampling.contact_choice as cc
    from mrlib.datasets.synthetic import synthetic_walk
    from mrlib.model.checkpoint import load_checkpoint, save_checkpoint
    from mrlib.model.config import ModelConfig, TrainConfig
    from mrlib.model.trained import load_model
    from mrlib.training.data import TrainingSet
    from mrlib.training.trainer import train, train_or_reuse

    tiny = TrainConfig(
        model=ModelConfig(num_levels=2, gen_hidden=(24,), disc_hidden=(24,)),
        block_iterations=(1,), n_critic=1, checkpoint_every=0,
    )  # fmt: skip
    calls = []
    monkeypatch.setattr(cc, "choose_contact_reading", lambda m: calls.append(m) or ("walk_sad",))
    data = TrainingSet.from_motions([synthetic_walk("walk_sad", seconds=3.0, fps=10.0)])
    ckpt = train(data, tiny, tmp_path / "run", progress=False).checkpoint
    assert len(calls) == 1
    assert load_checkpoint(ckpt)["contact_at_rate"] == ["walk_sad"]
    assert load_model(ckpt).contact_at_rate == ("walk_sad",)
    train(None, None, tmp_path / "run", resume=ckpt, progress=False)
    assert len(calls) == 1  # kept, not chosen again
    state = load_checkpoint(ckpt)
    del state["contact_at_rate"], state["checksum"]
    save_checkpoint(ckpt, state)
    old = load_model(ckpt)
    assert old.contact_at_rate is None
    drawn = generate(old, "walk_sad", length=30, seed=0, sampler=Sampler(fix_contacts=False))
    assert drawn.meta["sampler"]["match_contact_rate"] is False
    reused, rec = train_or_reuse(data, tiny, tmp_path / "run", progress=False)
    assert rec.reused and reused.contact_at_rate == ("walk_sad",) and len(calls) == 2
    assert load_checkpoint(ckpt)["contact_at_rate"] == ["walk_sad"]  # written, once
    train_or_reuse(data, tiny, tmp_path / "run", progress=False)
    assert len(calls) == 2
    # a run stopped early chooses nothing; resumed to its end, it chooses
    tiny3 = dataclasses.replace(tiny, block_iterations=(3,))

    def stop(trainer, losses):
        if (trainer.block, trainer.iteration) == (0, 1):
            raise KeyboardInterrupt

    res = train(data, tiny3, tmp_path / "stopped", progress=False, callback=stop)
    assert res.interrupted and len(calls) == 2
    assert "contact_at_rate" not in load_checkpoint(res.checkpoint)
    assert load_model(res.checkpoint).contact_at_rate is None
    train(None, None, tmp_path / "stopped", resume=res.checkpoint, progress=False)
    assert len(calls) == 3 and load_checkpoint(res.checkpoint)["contact_at_rate"] == ["walk_sad"]


def test_a_choice_that_fails_leaves_the_model_at_the_papers_cut(model, monkeypatch):
    import mrlib.sampling.contact_choice as cc
    from mrlib.errors import MrlibError
    from mrlib.model.checkpoint import CheckpointWarning

    def fail(m):
        raise MrlibError("no draw")

    monkeypatch.setattr(cc, "choose_contact_reading", fail)
    monkeypatch.setattr(model, "contact_at_rate", None)
    with pytest.warns(CheckpointWarning, match="no draw"):
        assert cc.settle_contact_reading(model) == ()
    assert model.contact_at_rate == ()
