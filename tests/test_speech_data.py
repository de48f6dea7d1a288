"""The synthetic co-speech set (mrlib.speech.synthetic) and the folder loaders (.data)."""

import numpy as np
import pytest
import soundfile

import mrlib.speech.gestures as gestures
import mrlib.speech.synthetic as sd
from mrlib.errors import MotionFileError, MotionValueError
from mrlib.io import load_motion, save_motion
from mrlib.io.paths import default_data_dir
from mrlib.representation.body import load_body_model
from mrlib.representation.skeleton import JOINT_NAMES
from mrlib.speech import (
    AudioFileError,
    SpeechFeatureExtractor,
    SpeechSynthesisError,
    beat_alignment_score,
    detect_onsets,
    energy_envelope,
    hand_speed,
    load_base_motions,
    load_paired_folder,
    load_unpaired_folder,
    make_synthetic_pair,
    speech_motion_correlation,
    standing_base,
    synthesize_speech,
    synthetic_corpus,
)
from mrlib.speech.gestures import loop_motion, quiet_window
from mrlib.speech.synthetic import SENTENCES, VOICES, corpus_text

SR = 16_000
DATA = default_data_dir()
needs_espeak = pytest.mark.skipif(
    not sd.espeak_available(),
    reason="eSpeak NG is not installed (pip install espeakng-loader, part of mrlib[speech])",
)
needs_data = pytest.mark.skipif(
    not (DATA / "data").is_dir(), reason=f"Bandai Namco data not found at {DATA}"
)
LOGMEL = SpeechFeatureExtractor(kind="logmel", n_mels=20)


@pytest.fixture(scope="module")
def body():
    return load_body_model()


# -- espeak --------------------------------------------------------------------------------
@needs_espeak
def test_espeak_speech_has_a_plausible_duration():
    text = "The museum opens at ten, but the best time to come is just before closing."
    slow = synthesize_speech(text, "en-us", 140)
    fast = synthesize_speech(text, "en-gb", 200)
    # 16 words: 6.9 s at 140 wpm, 4.8 s at 200 wpm; espeak adds little silence
    assert 4.5 < len(slow) / SR < 9.0 and 3.0 < len(fast) / SR < 6.5
    assert len(fast) < 0.85 * len(slow)
    assert np.abs(slow).max() > 0.05 and slow.dtype == np.float32
    paused = synthesize_speech(
        sd.with_pauses(text, np.random.default_rng(0)), "en-us", 140, ssml=True
    )
    assert len(paused) > len(slow) + 0.1 * SR  # one comma and one full stop pause
    with pytest.raises(SpeechSynthesisError, match="voice"):
        synthesize_speech("hello", "xx-none")


@needs_espeak
def test_the_same_text_gives_the_same_samples():
    text = sd.with_pauses("Hello there, how are you today?", np.random.default_rng(0))
    a = synthesize_speech(text, "en-gb+m3", 160, ssml=True)
    b = synthesize_speech(text, "en-gb+m3", 160, ssml=True)
    assert np.array_equal(a, b)
    # the variant changes the voice; a language code picks its voice file
    assert not np.array_equal(a, synthesize_speech(text, "en-gb", 160, ssml=True))


@needs_espeak
@pytest.mark.parametrize("voice", [v for v in sd.VOICES if "+f" in v])
def test_voices_with_breath_noise_speak_the_same_every_time(voice):
    """The female variants add breath noise from eSpeak NG's random numbers, which it seeds
    from the clock: unseeded, two runs of the same text differed (and so did notebook 04's
    model from run to run)."""
    from mrlib.speech import espeak

    if espeak.espeak_backend() != "library":
        pytest.skip("the espeak-ng program cannot be seeded; the library back end is")
    text = "Look at the light on the left, it falls exactly on her hands."
    assert np.array_equal(synthesize_speech(text, voice, 160), synthesize_speech(text, voice, 160))


def test_missing_espeak_is_a_clear_error(monkeypatch):
    from mrlib.speech import espeak

    monkeypatch.setattr(espeak, "_library_available", lambda: False)
    monkeypatch.setattr(espeak.shutil, "which", lambda name: None)
    assert not sd.espeak_available()
    with pytest.raises(SpeechSynthesisError, match="espeakng-loader"):
        synthesize_speech("hello")
    with pytest.raises(SpeechSynthesisError, match="backend"):
        synthesize_speech("hello", backend="festival")


# -- base motion ---------------------------------------------------------------------------
def test_loop_motion_goes_back_and_forth():
    m = standing_base(seconds=1.0, fps=10)
    looped = loop_motion(m, 35)
    idx = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0, 1]
    assert looped.num_frames == 35 and np.array_equal(looped.poses[:20], m.poses[idx])
    assert loop_motion(m, 4).num_frames == 4
    with pytest.raises(MotionValueError):
        loop_motion(m, 0)


@needs_data
def test_bandai_bases_are_resting_stances(body):
    bases = load_base_motions(DATA, fps=25.0, body=body)
    assert len(bases) == len(gestures.BASE_CLIPS)
    for b in bases:
        j = body.motion_joints(b)
        assert b.fps == 25 and b.num_frames >= 36
        assert (j[:, [20, 21], 1] < j[:, None, 0, 1]).all()  # wrists below the pelvis
        assert hand_speed(b, body).mean() < 0.15
    # a clip whose only calm moment is a held gesture is refused as a base
    raw = load_motion(DATA / "data" / "dataset-1_guide_normal_001.bvh")
    with pytest.raises(MotionValueError, match="resting stance"):
        quiet_window(raw, 1.5, body)


# -- synthetic pairs -----------------------------------------------------------------------
@needs_espeak
def test_pair_changes_only_arms_and_head(body):
    base = standing_base(seconds=2.0, fps=25.0)
    wav, sr, m = make_synthetic_pair(SENTENCES[3], VOICES[1], 7, base)
    assert sr == SR and m.fps == 25 and m.num_frames == round(len(wav) / SR * 25)
    assert m.meta["synthetic"] and m.meta["sentence"] == SENTENCES[3] and m.meta["beats_s"]
    ref = loop_motion(base, m.num_frames)
    changed = {JOINT_NAMES[j] for j in range(24) if not np.allclose(m.poses[:, j], ref.poses[:, j])}
    arms = {f"{s}_{p}" for s in ("left", "right") for p in ("shoulder", "elbow", "wrist")}
    assert changed == arms | {"head"}
    # the gesture raises the hands in front of the body while speaking
    jm, jb = body.motion_joints(m), body.motion_joints(ref)
    talking = energy_envelope(wav, sr, m.fps, m.num_frames) > -20
    assert (jm[talking, 21, 2] - jb[talking, 21, 2]).mean() > 0.03  # right wrist forward
    assert (jm[talking, 21, 1] - jb[talking, 21, 1]).mean() > 0.03  # and up
    wav2, _, m2 = make_synthetic_pair(SENTENCES[3], VOICES[1], 7, base)
    assert np.array_equal(wav, wav2) and np.array_equal(m.poses, m2.poses)  # seeded


@needs_espeak
@needs_data
def test_hand_speed_follows_speech_energy(body):
    """Loudness/hand-speed correlation of synthetic pairs vs the shuffled-audio control
    (each motion against the next pair's audio); printed with ``pytest -s``."""
    bases = load_base_motions(DATA, fps=25.0, body=body)
    pairs = []
    for k in range(4):
        wav, sr, m = make_synthetic_pair(corpus_text(k), VOICES[k], k, bases[k])
        pairs.append((wav, m, hand_speed(m, body), detect_onsets(wav, sr)))
    r, r_ctl, ba, ba_ctl = [], [], [], []
    for k, (wav, m, speed, onsets) in enumerate(pairs):
        other_wav, _, _, other_onsets = pairs[(k + 1) % len(pairs)]
        env = energy_envelope(wav, SR, m.fps, m.num_frames)
        env_ctl = np.resize(energy_envelope(other_wav, SR, m.fps), m.num_frames)
        r.append(speech_motion_correlation(env, m, speed=speed).r)
        r_ctl.append(speech_motion_correlation(env_ctl, m, speed=speed).r)
        ba.append(beat_alignment_score(onsets, m, speed=speed))
        ba_ctl.append(beat_alignment_score(other_onsets, m, speed=speed))
    print(
        f"\nr = {np.round(r, 2)} (mean {np.mean(r):.3f}); control {np.round(r_ctl, 2)} "
        f"(mean {np.mean(r_ctl):.3f}); beat alignment {np.mean(ba):.3f} vs {np.mean(ba_ctl):.3f}"
    )
    assert np.mean(r) > 0.3 and min(r) > 0.2
    assert np.mean(r_ctl) < np.mean(r) - 0.1
    assert np.mean(ba) > np.mean(ba_ctl) + 0.05


# -- corpus and loaders --------------------------------------------------------------------
@needs_espeak
def test_corpus_round_trip(tmp_path):
    bases = [standing_base(seconds=1.5, fps=25.0, seed=s) for s in range(2)]
    corpus = synthetic_corpus(2, 1, tmp_path, base_motions=bases)
    assert len(corpus.paired) == 2 and len(corpus.unpaired) == 1 and corpus.manifest.is_file()
    pairs = load_paired_folder(tmp_path / "paired", LOGMEL)
    assert [p.name for p in pairs] == ["synthetic_0000", "synthetic_0001"]
    for p in pairs:
        assert p.features.shape[1] == 23 and p.fps == 50 and p.motion.fps == 25
        assert abs(p.duration - p.motion.duration) < 0.05
        assert abs(p.features.shape[0] / 50 - p.duration) < 0.05
    clips = load_unpaired_folder(tmp_path / "unpaired", LOGMEL)
    assert len(clips) == 1 and clips[0].duration > 2.0
    wav = next((tmp_path / "unpaired").glob("*.wav"))
    data, sr = soundfile.read(str(wav))
    soundfile.write(str(tmp_path / "unpaired" / "other.ogg"), data, sr)  # read as a .wav is
    assert [c.name for c in load_unpaired_folder(tmp_path / "unpaired", LOGMEL)] == [
        "other",
        wav.stem,
    ]


def _write_pair(folder, stem, seconds=2.0, motion_seconds=None, ext=".npz", sr=SR):
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(int(seconds * sr)) / sr
    soundfile.write(str(folder / f"{stem}.wav"), 0.2 * np.sin(2 * np.pi * 150 * t), sr)
    if motion_seconds is not False:
        m = standing_base(seconds if motion_seconds is None else motion_seconds, fps=25)
        save_motion(m, folder / f"{stem}{ext}")


def test_paired_loader_errors(tmp_path):
    d = tmp_path / "set"
    _write_pair(d, "a")
    _write_pair(d, "b", motion_seconds=False)  # audio without motion
    with pytest.raises(MotionFileError, match="missing partner: no motion file b.npz") as e:
        load_paired_folder(d, LOGMEL)
    assert e.value.path == d / "b.wav"
    with pytest.warns(UserWarning, match="skipped"):
        assert [p.name for p in load_paired_folder(d, LOGMEL, strict=False)] == ["a"]
    (d / "b.wav").unlink()
    save_motion(standing_base(2.0), d / "c.npz")  # motion without audio
    with pytest.raises(MotionFileError, match="no audio file c.wav"):
        load_paired_folder(d, LOGMEL)
    (d / "c.npz").unlink()
    _write_pair(d, "a", ext=".bvh")  # a.npz and a.bvh
    with pytest.raises(MotionFileError, match="ambiguous"):
        load_paired_folder(d, LOGMEL)
    (d / "a.bvh").unlink()
    data, sr = soundfile.read(str(d / "a.wav"))
    soundfile.write(str(d / "a.flac"), data, sr)  # a.wav and a.flac: which is the take's?
    with pytest.raises(AudioFileError, match="ambiguous partner: a.flac and a.wav"):
        load_paired_folder(d, LOGMEL)
    (d / "a.flac").unlink()
    _write_pair(d, "long", seconds=2.0, motion_seconds=4.0)
    with pytest.raises(MotionFileError, match="lasts 4.00 s but long.wav lasts 2.00 s"):
        load_paired_folder(d, LOGMEL)
    (d / "long.npz").unlink()
    _write_pair(d, "long", seconds=0.5)
    with pytest.raises(AudioFileError, match="at least 1 s"):
        load_paired_folder(d, LOGMEL)
    (d / "long.npz").unlink()
    (d / "long.wav").unlink()
    _write_pair(d, "low", sr=4000)
    with pytest.raises(AudioFileError, match="below 8000 Hz"):
        load_paired_folder(d, LOGMEL)
    (d / "low.npz").unlink()
    (d / "low.wav").unlink()
    # motion in its own folder, resampled on load
    m_dir = tmp_path / "motion"
    m_dir.mkdir()
    (d / "a.npz").rename(m_dir / "a.npz")
    (pair,) = load_paired_folder(d, LOGMEL, motion_dir=m_dir, motion_fps=20)
    assert pair.motion.fps == 20 and pair.motion_path == m_dir / "a.npz"
    with pytest.raises(AudioFileError, match="no audio files"):
        load_unpaired_folder(m_dir, LOGMEL)


def test_max_mismatch_on_the_command_line(tmp_path, monkeypatch, capsys):
    """Audio 1.5 s longer than its motion: refused at the default 1 s with the flag
    named, accepted (and cut to the motion) with --max-mismatch 2."""
    import mrlib.speech
    from mrlib.app.cli import main

    d = tmp_path / "paired"
    _write_pair(d, "talk", seconds=3.5, motion_seconds=2.0)
    args = ["train-speech", str(d), "--preset", "speech_demo", "--iterations", "1"]
    assert main(args + ["--out", str(tmp_path / "a"), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "lasts 2.00 s but talk.wav lasts 3.50 s" in err and "--max-mismatch" in err

    class Reached(BaseException):  # past the loading, into training
        pass

    def stop(data, *a, **k):
        assert data.num_paired == 1
        assert abs(data.paired_features[0].shape[0] / 50 - 2.0) < 0.05  # cut to the motion
        raise Reached

    monkeypatch.setattr(mrlib.speech, "speech_train", stop)
    with pytest.raises(Reached):
        main(args + ["--out", str(tmp_path / "b"), "--max-mismatch", "2"])
    for bad in ("-1", "nan", "x", "1e9"):
        with pytest.raises(SystemExit):
            main(args + ["--out", str(tmp_path / "c"), "--max-mismatch", bad])
        assert "--max-mismatch" in capsys.readouterr().err


def test_a_file_without_its_partner_can_be_skipped_from_the_command_line(
    tmp_path, monkeypatch, capsys
):
    import mrlib.speech
    from mrlib.app.cli import main

    d = tmp_path / "paired"
    _write_pair(d, "a")
    _write_pair(d, "b", motion_seconds=False)  # audio without its motion
    args = ["train-speech", str(d), "--preset", "speech_demo", "--iterations", "1", "--no-progress"]
    assert main(args + ["--out", str(tmp_path / "x")]) == 1
    assert "--skip-unpaired-files" in capsys.readouterr().err

    class Reached(BaseException):
        pass

    def stop(data, *a, **k):
        assert data.num_paired == 1
        raise Reached

    monkeypatch.setattr(mrlib.speech, "speech_train", stop)
    with pytest.raises(Reached):
        main(args + ["--out", str(tmp_path / "y"), "--skip-unpaired-files"])
    assert "skipped, no motion file b.npz" in capsys.readouterr().err


def test_split_pair_keeps_the_last_seconds_out(tmp_path):
    from mrlib.speech import split_pair

    _write_pair(tmp_path, "talk", seconds=8.0)
    (pair,) = load_paired_folder(tmp_path, LOGMEL)
    head, tail = split_pair(pair, 3.0)
    assert head.motion.num_frames == 125 and abs(head.duration - 5.0) < 0.03
    assert abs(head.features.shape[0] / 50 - 5.0) < 0.05
    assert tail.motion.num_frames == 75 and len(tail.wav) == 3 * SR
    # the two parts are the pair's frames, in order, with nothing left over or repeated
    assert np.array_equal(
        np.concatenate([head.motion.poses, tail.motion.poses]), pair.motion.poses[:200]
    )
    for bad in (0.0, 7.0, 1.0):
        with pytest.raises(MotionValueError, match="at least 2 s"):
            split_pair(pair, bad)


def test_per_utterance_features_do_not_change_with_the_recording_level():
    """A voice recorded 20 dB louder (or by another microphone's gain) reaches the model
    as the same features; the training-set scale sees a shifted voice."""
    rng = np.random.default_rng(0)
    t = np.arange(3 * SR) / SR
    wav = (0.05 * np.sin(2 * np.pi * 180 * t) * (1 + np.sin(2 * np.pi * 1.3 * t))).astype(
        np.float32
    )
    wav += 0.003 * rng.standard_normal(len(wav)).astype(np.float32)
    per = SpeechFeatureExtractor(kind="logmel", n_mels=20, per_utterance=True)
    raw = SpeechFeatureExtractor(kind="logmel", n_mels=20)
    a, b = per(wav, SR), per(10 * wav, SR)
    assert float((a - b).abs().max()) < 1e-3
    assert float((raw(wav, SR) - raw(10 * wav, SR)).abs().mean()) > 1.0
    assert float(a.mean(0).abs().max()) < 1e-4
    sd_ = a.std(0)  # every dimension at unit s.d., or constant (held at its floor)
    assert bool((((sd_ - 1).abs() < 1e-3) | (sd_ < 1e-2)).all())


def test_the_feature_scale_on_the_command_line(tmp_path, monkeypatch):
    """train-speech standardises the features per utterance unless told otherwise; the
    choice travels with the training set's feature config (and so with the model)."""
    import mrlib.speech
    from mrlib.app.cli import main

    d = tmp_path / "paired"
    _write_pair(d, "talk", seconds=3.0)
    seen = []

    class Reached(BaseException):
        pass

    def stop(data, *a, **k):
        seen.append(data.feature_config.per_utterance)
        raise Reached

    monkeypatch.setattr(mrlib.speech, "speech_train", stop)
    args = ["train-speech", str(d), "--preset", "speech_demo", "--iterations", "1"]
    for k, extra in enumerate(
        ([], ["--feature-scale", "training-set"], ["--feature-scale", "utterance"])
    ):
        with pytest.raises(Reached):
            main(args + ["--out", str(tmp_path / f"r{k}"), *extra])
    assert seen == [True, False, True]
