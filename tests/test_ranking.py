"""Critic-ranked sampling (``mrlib.sampling.ranking``, ``Sampler.candidates``): which draw is
kept, that one candidate is the plain sampler, and that batching changes nothing."""

import dataclasses

import numpy as np
import pytest
import torch
import torch.nn.functional as F

import mrlib.sampling.generation as generation
from mrlib.errors import MotionValueError
from mrlib.sampling.conditions import Condition
from mrlib.sampling.generation import generate, label_inputs, sample_features, sample_ranked
from mrlib.sampling.ranking import best_candidates, critic_scores
from mrlib.sampling.sampler import CANDIDATES, Sampler


@pytest.fixture(scope="module")
def model(normal_sad_model):
    """A plumbing model (two iterations per block): its samples mean nothing."""
    return normal_sad_model


def _inputs(model, label="walk_sad", length=40):
    W = Condition.label(label).weights(model)
    return label_inputs(model, W, length, Sampler())


def test_a_loaded_checkpoint_brings_its_critics(model):
    assert model.critics is not None and len(model.critics) == model.num_levels
    assert not any(p.requires_grad for p in model.critics.parameters())


def test_one_candidate_is_the_plain_draw(model):
    lengths, amp, conds = _inputs(model)
    plain = sample_features(model, conds, lengths, amp, seed=3, num_samples=2, keep=True)
    one = sample_ranked(model, conds, lengths, amp, 3, 2, 1)
    assert all(torch.equal(a, b) for a, b in zip(plain, one, strict=True))


def _by_hand_scores(model, outs, conds):
    """Each level's mean patch score, the critic run with F.pad's reflect padding."""
    rows = []
    for i, x in enumerate(outs):
        critic = model.critics[i]
        p = critic.body.pad
        index = F.pad(torch.arange(x.shape[-1], dtype=torch.float32)[None, None], (p, p), "reflect")
        cond = conds[i].expand(x.shape[0], x.shape[-1], -1) if critic.cond_dim else None
        rows.append(critic(x, index.long(), cond).mean(1))
    return torch.stack(rows)  # (L, N)


def test_the_kept_draw_is_the_critics_best_of_its_candidates(model):
    K, B = 4, 3
    lengths, amp, conds = _inputs(model)
    # candidate j of sample b is noise stream b K + j: the plain sampler's sample b K + j
    every = sample_features(model, conds, lengths, amp, seed=7, num_samples=B * K, keep=True)
    cs = [c.expand(B * K, -1, -1) for c in conds]
    scores = _by_hand_scores(model, every, cs)
    assert torch.allclose(critic_scores(model, every, cs), scores, atol=1e-6)
    z = scores.reshape(-1, B, K)
    z = (z - z.mean(-1, keepdim=True)) / z.std(-1, keepdim=True)
    expected = z.sum(0).argmax(-1) + torch.arange(B) * K
    kept = sample_ranked(model, conds, lengths, amp, 7, B, K)
    for level, out in enumerate(kept):
        assert torch.equal(out, every[level][expected])
    assert len(set(expected.tolist())) == B  # three different draws kept
    assert not torch.equal(kept[-1], every[-1][torch.arange(B) * K])  # not always the first


def test_best_candidates_standardises_each_level_before_summing():
    # level 2's scores spread 20 times wider than level 1's: summed raw, it alone decides
    scores = torch.tensor([[10.0, 0.0, 9.0], [100.0, 200.0, 0.0]])
    assert scores.sum(0).argmax() == 1
    assert best_candidates(scores, 3).tolist() == [0]  # z: (0.67, -1.15, 0.49) + (0, 1, -1)
    two = torch.cat([scores, scores.flip(1)], 1)  # a second sample: its best is its last
    assert best_candidates(two, 3).tolist() == [0, 5]


def test_batches_of_ranked_samples_change_nothing(model, monkeypatch):
    lengths, amp, conds = _inputs(model)
    whole = sample_ranked(model, conds, lengths, amp, 5, 3, 4)
    monkeypatch.setattr(generation, "MAX_SAMPLE_FRAMES", lengths[-1] * 4)  # one sample a batch
    split = sample_ranked(model, conds, lengths, amp, 5, 3, 4)
    assert all(torch.equal(a, b) for a, b in zip(whole, split, strict=True))


def test_a_model_without_critics_draws_once(model):
    bare = dataclasses.replace(model, critics=None)
    a = generate(bare, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False))
    b = generate(model, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False, candidates=1))
    assert np.array_equal(a.poses, b.poses)


def test_generate_ranks_by_default_and_records_it(model):
    m = generate(model, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False))
    one = generate(model, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False, candidates=1))
    assert m.meta["sampler"]["candidates"] == CANDIDATES > 1
    assert not np.array_equal(m.poses, one.poses)


@pytest.mark.parametrize("bad", [0, -1, CANDIDATES * 100, 2.5, True, "4", None])
def test_candidates_are_a_whole_number_in_range(bad):
    with pytest.raises(MotionValueError, match="candidates"):
        Sampler(candidates=bad)


def test_candidates_take_numpy_integers():
    assert Sampler(candidates=np.int64(3)).candidates == 3


def test_measurements_of_the_generator_draw_once_by_default():
    from mrlib.sampling.sampler import raw_sampler

    assert raw_sampler().candidates == 1 and not raw_sampler().fix_contacts
    assert Sampler().candidates == CANDIDATES


def test_a_model_with_no_trained_level_draws_once(model):
    untrained = dataclasses.replace(model, trained_levels=0)
    a = generate(untrained, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False))
    b = generate(model, "walk_sad", seed=2, sampler=Sampler(fix_contacts=False, candidates=1))
    assert np.array_equal(a.poses, b.poses)
