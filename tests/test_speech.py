"""Speech features, alignment to pyramid levels, and the speech/motion measures."""

from pathlib import Path

import numpy as np
import pytest
import torch

from mrlib.errors import ClipTooShortError, MotionValueError
from mrlib.model.pyramid import pyramid_lengths
from mrlib.representation.motion import Motion
from mrlib.speech import (
    FEATURE_FPS,
    FRAME_OFFSET_S,
    SPEECH_NUM_LEVELS,
    AudioFileError,
    SpeechFeatureConfig,
    SpeechFeatureExtractor,
    SpeechModelError,
    SpeechNormalizer,
    align_to_levels,
    autocorrelation_pitch,
    beat_alignment_score,
    detect_onsets,
    energy_envelope,
    hand_speed,
    interpolate_to_fps,
    lagged_correlation,
    levels_to_residuals,
    load_audio,
    load_wavlm,
    log_mel_features,
    motion_beats,
    num_feature_frames,
    residuals_to_levels,
    speech_conditions,
    speech_motion_correlation,
    stack_conditions,
)
from mrlib.speech.align import _interpolate_naive
from mrlib.speech.features import WAVLM_DEFAULT_ID

SR = 16_000
ROOT = Path(__file__).resolve().parents[1]
rng = np.random.default_rng(0)


def _tone(seconds=2.0, f0=150.0, f1=None, amp=0.3):
    t = np.arange(int(seconds * SR)) / SR
    f = np.full_like(t, f0) + (0 if f1 is None else (f1 - f0) * t / seconds)
    return (np.asarray(amp) * np.sin(2 * np.pi * np.cumsum(f) / SR)).astype(np.float32)


# -- alignment -----------------------------------------------------------------------------
def test_levels_have_the_pyramid_lengths():
    lengths = pyramid_lengths(250, SPEECH_NUM_LEVELS)
    feats = torch.randn(500, 7)  # 10 s at 50 fps
    for method in ("area", "linear"):
        levels = align_to_levels(feats, 50.0, 25.0, lengths, offset_s=FRAME_OFFSET_S, method=method)
        assert [tuple(x.shape) for x in levels] == [(n, 7) for n in lengths]
        res = levels_to_residuals(levels)
        assert [tuple(x.shape) for x in res] == [(n, 7) for n in lengths]


def test_interpolation_matches_the_naive_oracle_and_keeps_time():
    feats = torch.randn(123, 5, dtype=torch.float64)
    fast = interpolate_to_fps(feats, 50.0, 30.0, 80, offset_s=0.0125)
    assert torch.allclose(fast, torch.from_numpy(_interpolate_naive(feats, 50.0, 30.0, 80, 0.0125)))
    # a feature equal to its own frame time lands on the motion frame times exactly
    ramp = (torch.arange(200, dtype=torch.float64) / 50 + 0.0125)[:, None]
    out = interpolate_to_fps(ramp, 50.0, 25.0, 90, offset_s=0.0125)[:, 0]
    t = torch.arange(90, dtype=torch.float64) / 25
    assert torch.allclose(out[1:], t[1:]) and out[0] == ramp[0, 0]  # frame 0 holds the edge


def test_residuals_invert_exactly():
    lengths = pyramid_lengths(120, SPEECH_NUM_LEVELS)
    levels = align_to_levels(torch.randn(260, 6, dtype=torch.float64), 50, 25, lengths)
    back = residuals_to_levels(levels_to_residuals(levels))
    for a, b in zip(levels, back, strict=True):
        assert torch.allclose(a, b, atol=1e-12, rtol=0)
    # the residual of level i is up(level i-1) - level i, with the paper's sign
    up = torch.nn.functional.interpolate(levels[0].T[None], size=lengths[1], mode="linear")
    assert torch.allclose(levels_to_residuals(levels)[1], up[0].T - levels[1])


def test_constant_features_give_zero_residuals():
    c = torch.tensor([0.5, -2.0, 3.0])
    lengths = pyramid_lengths(100, SPEECH_NUM_LEVELS)
    for method in ("area", "linear"):
        res = levels_to_residuals(align_to_levels(c.expand(230, 3), 50, 25, lengths, method=method))
        assert torch.allclose(res[0], c.expand(lengths[0], 3))
        assert all(r.abs().max() < 1e-6 for r in res[1:])


def test_alignment_rejects_bad_inputs():
    with pytest.raises(MotionValueError):
        align_to_levels(torch.randn(10), 50, 25, [3, 5])
    with pytest.raises(MotionValueError):
        align_to_levels(torch.full((10, 2), float("nan")), 50, 25, [3, 5])
    with pytest.raises(MotionValueError, match="increasing"):
        align_to_levels(torch.randn(10, 2), 50, 25, [5, 5])


def test_normalizer_and_conditions_for_a_batch():
    clips = [torch.randn(n, 4) * 3 + 7 for n in (180, 260)]
    norm = SpeechNormalizer.fit(clips)
    z = torch.cat([norm.normalize(c) for c in clips])
    assert torch.allclose(z.mean(0), torch.zeros(4), atol=1e-5)
    assert torch.allclose(z.std(0), torch.ones(4), atol=1e-4)
    assert torch.allclose(SpeechNormalizer.from_state_dict(norm.state_dict()).mean, norm.mean)
    with pytest.raises(MotionValueError, match="fitted on 4"):
        norm.normalize(torch.randn(5, 3))
    conds = [speech_conditions(c, 50, 25, normalizer=norm) for c in clips]
    # unpaired audio: motion length from the audio, 10 levels
    assert [len(c) for c in conds] == [10, 10] and conds[0][-1].shape == (90, 4)
    batch, table = stack_conditions(conds)
    assert table.shape == (2, 10) and table[1, -1] == 130
    assert [tuple(b.shape) for b in batch] == [(2, int(table[:, i].max()), 4) for i in range(10)]
    assert torch.equal(batch[-1][0, :90], conds[0][-1])


# -- features ------------------------------------------------------------------------------
def test_log_mel_features_on_a_chirp():
    amp = np.where(np.arange(2 * SR) < SR, 0.1, 0.5)
    wav = _tone(2.0, 100.0, 400.0, amp)
    feats = log_mel_features(wav, SR)
    T = num_feature_frames(len(wav))
    assert feats.shape == (T, 83) and T == 99  # (32000 - 400) // 320 + 1: 50 fps
    assert abs(T / 2.0 - FEATURE_FPS) < 1
    energy = feats[:, 80]
    gain = energy[60:].mean() - energy[:40].mean()  # 5x amplitude = +2 ln 5 in log power
    assert abs(gain - 2 * np.log(5)) < 0.05
    t = np.arange(T) / 50 + FRAME_OFFSET_S
    f0 = 100 * 2 ** feats[:, 82].numpy() / 1  # voiced frames: log2(F0/100) * voicing ~ 1
    true = 100 + 150 * t
    assert np.median(np.abs(f0[5:-5] / true[5:-5] - 1)) < 0.03
    noise = log_mel_features(rng.normal(0, 0.1, SR).astype(np.float32), SR)
    assert noise[:, 81].mean() < 0.5 < feats[:, 81].mean()
    # other rates are resampled to 16 kHz first; stereo is mixed down
    stereo = np.stack([_tone(1.0), _tone(1.0)], 1)
    assert log_mel_features(stereo, SR).shape == (49, 83)
    with pytest.raises(ClipTooShortError):
        log_mel_features(np.zeros(300, np.float32), SR)


def test_pitch_and_voicing_ignore_a_dc_offset():
    # a voiced glide with breath noise; an offset 30 dB under it moves neither
    wav = _tone(2.0, 100.0, 300.0, 0.3) + rng.normal(0, 0.02, 2 * SR).astype(np.float32)
    f0, voicing = autocorrelation_pitch(torch.from_numpy(wav))
    for dc in (0.01, 0.05):
        f0_dc, voicing_dc = autocorrelation_pitch(torch.from_numpy(wav + np.float32(dc)))
        assert (voicing_dc - voicing).abs().max() < 0.05
        assert (torch.log2(f0_dc / f0)).abs().max() < 0.05


def _tiny_wavlm(path):
    from transformers import WavLMConfig, WavLMModel

    torch.manual_seed(0)
    cfg = WavLMConfig(
        hidden_size=32,
        num_hidden_layers=2,
        num_attention_heads=2,
        intermediate_size=64,
        conv_dim=(16,) * 7,
        num_conv_pos_embeddings=16,
        num_conv_pos_embedding_groups=4,
        num_buckets=32,
        max_bucket_distance=100,
    )
    WavLMModel(cfg).save_pretrained(path)
    return path


@pytest.fixture
def one_thread():
    """A tiny network gains nothing from threads, and on a busy 2-core machine OpenMP
    spin-waiting makes small ops ~1000x slower."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def test_wavlm_tiny_random_model(tmp_path, monkeypatch, one_thread):
    from mrlib.speech import wavlm_features

    path = _tiny_wavlm(tmp_path / "wavlm")
    wav = rng.normal(0, 0.1, int(0.8 * SR) + 123).astype(np.float32)
    ex = SpeechFeatureExtractor(SpeechFeatureConfig(kind="wavlm", wavlm_path=str(path), layer=1))
    feats = ex(wav, SR)
    assert feats.shape == (num_feature_frames(len(wav)), 32) == (40, 32) and ex.dim == 32
    assert ex.fps == 50.0 and torch.isfinite(feats).all()
    # 44.1 kHz input is resampled: same duration, same frame count
    wav44 = np.interp(np.arange(int(len(wav) * 44100 / SR)) * SR / 44100, np.arange(len(wav)), wav)
    assert ex(wav44.astype(np.float32), 44100).shape[0] in (39, 40)
    # layer choice: index into hidden_states, or the mean of all of them
    model, _ = load_wavlm(path)
    mean = wavlm_features(model, wav, layer="mean")
    assert mean.shape == feats.shape and not torch.allclose(mean, feats)
    with pytest.raises(SpeechModelError, match=r"\[0, 2\]"):
        wavlm_features(model, wav, layer=5)
    # chunked inference: same frame grid; identical when the chunk covers the clip
    whole = wavlm_features(model, wav, layer=1, chunk_seconds=None)
    assert torch.allclose(whole, feats) and torch.allclose(
        whole, wavlm_features(model, wav, layer=1, chunk_seconds=10.0)
    )
    chunked = wavlm_features(model, wav, layer=1, chunk_seconds=0.4, context_seconds=0.1)
    assert chunked.shape == whole.shape
    # the environment variable is honoured
    monkeypatch.setenv("MRLIB_WAVLM_PATH", str(path))
    assert load_wavlm(None)[0].config.hidden_size == 32


def test_missing_wavlm_weights_say_what_to_do(tmp_path, monkeypatch):
    monkeypatch.delenv("MRLIB_WAVLM_PATH", raising=False)
    for where in (tmp_path / "nope", tmp_path):  # no folder; a folder without config.json
        with pytest.raises(SpeechModelError) as e:
            load_wavlm(where)
        msg = str(e.value)
        assert str(where) in msg and "MRLIB_WAVLM_PATH" in msg and WAVLM_DEFAULT_ID in msg
        assert "logmel" in msg
    monkeypatch.setenv("MRLIB_WAVLM_PATH", str(tmp_path / "nope"))
    with pytest.raises(SpeechModelError, match=r"\$MRLIB_WAVLM_PATH"):
        SpeechFeatureExtractor(kind="wavlm")(np.zeros(SR, np.float32), SR)
    monkeypatch.delenv("MRLIB_WAVLM_PATH")
    from huggingface_hub import try_to_load_from_cache

    if isinstance(try_to_load_from_cache(WAVLM_DEFAULT_ID, "config.json"), str):
        return  # this machine has the real weights cached: nothing is missing
    with pytest.raises(SpeechModelError, match="huggingface-cli download"):
        load_wavlm(None)


@pytest.mark.parametrize(
    "kw",
    [dict(chunk_seconds=0), dict(chunk_seconds=-5.0), dict(layer=True), dict(layer=-1),
     dict(n_mels=2.5), dict(n_mels=400), dict(n_mels=0), dict(kind="mfcc")],
)  # fmt: skip
def test_feature_settings_that_break_extraction_are_refused(kw):
    # chunk_seconds=0 ran one WavLM pass per frame; n_mels=400 left 88 bands empty
    with pytest.raises(MotionValueError):
        SpeechFeatureConfig(**kw)


def test_extractor_config_round_trip():
    c = SpeechFeatureConfig(kind="logmel", n_mels=40, pitch=False)
    assert SpeechFeatureConfig.from_dict(c.to_dict()) == c
    assert SpeechFeatureExtractor(c).dim == 41
    with pytest.raises(MotionValueError):
        SpeechFeatureConfig(kind="mfcc")
    # a model saved before per-utterance scaling existed keeps the training-set scale
    old = {k: v for k, v in c.to_dict().items() if k != "per_utterance"}
    assert SpeechFeatureConfig.from_dict(old).per_utterance is False
    c = SpeechFeatureConfig(kind="logmel", per_utterance=True)
    assert SpeechFeatureConfig.from_dict(c.to_dict()).per_utterance is True


# -- audio ---------------------------------------------------------------------------------
def test_load_audio_mixes_down_and_resamples(tmp_path):
    import soundfile

    stereo = np.stack([_tone(1.0, 200), _tone(1.0, 200)], 1)
    soundfile.write(str(tmp_path / "a.wav"), stereo[::1], SR)
    t = np.arange(44100) / 44100
    soundfile.write(str(tmp_path / "b.wav"), 0.3 * np.sin(2 * np.pi * 200 * t), 44100)
    a, sr_a = load_audio(tmp_path / "a.wav")
    b, sr_b = load_audio(tmp_path / "b.wav")
    assert sr_a == sr_b == SR and a.shape == b.shape == (SR,) and a.dtype == np.float32
    assert abs(np.abs(b).max() - 0.3) < 0.01
    soundfile.write(str(tmp_path / "low.wav"), np.zeros(4000), 4000)
    soundfile.write(str(tmp_path / "short.wav"), np.zeros(100), SR)
    (tmp_path / "junk.wav").write_bytes(b"not audio")
    (tmp_path / "folder.wav").mkdir()
    for name, why in [
        ("low", "below 8000"),
        ("short", "at least"),
        ("junk", "cannot read"),
        ("missing", "no such file"),
        ("folder", "a folder, not an audio file"),
    ]:
        with pytest.raises(AudioFileError, match=why) as e:
            load_audio(tmp_path / f"{name}.wav")
        assert e.value.path == tmp_path / f"{name}.wav"


def test_audio_arrays_in_memory_are_read_as_files_are():
    """What scipy's wav reader gives (integer PCM) and torchaudio's layout (channels
    first) give the samples a file gives; a rate the reader refuses is refused."""
    from mrlib.speech.audio import check_rate, fit_audio_length, to_mono

    x = _tone(0.5, 200)
    pcm = np.round(x * 32767).astype(np.int16)
    assert np.abs(to_mono(pcm) - x).max() < 1e-4
    u8 = np.round(x * 127 + 128).astype(np.uint8)
    assert np.abs(to_mono(u8) - x).max() < 1e-2
    assert np.array_equal(to_mono(np.stack([x, x])), to_mono(np.stack([x, x], 1)))
    assert check_rate(np.int64(44100)) == check_rate(44100.0) == 44100
    for bad in (4000, 0, float("nan"), 44100.5, "44100", True):
        with pytest.raises(MotionValueError, match="sample rate"):
            check_rate(bad)
    stereo = np.stack([x, -x], 1)  # cut or repeated along time, the channels kept
    longer = fit_audio_length(stereo, 3 * len(x) + 7)
    assert longer.shape == (3 * len(x) + 7, 2) and np.array_equal(
        longer[len(x) :][: len(x)], stereo
    )


def test_shipped_espeak_sample():
    wav, sr = load_audio(ROOT / "data_samples" / "speech" / "hello.wav")
    assert sr == SR and 3.0 < len(wav) / SR < 6.0
    onsets = detect_onsets(wav, sr)
    assert 2.0 < len(onsets) / (len(wav) / SR) < 8.0  # syllable-rate onsets
    feats = SpeechFeatureExtractor(kind="logmel")(wav, sr)
    assert feats.shape == (num_feature_frames(len(wav)), 83) and torch.isfinite(feats).all()


def test_energy_envelope_tracks_amplitude():
    amp = np.where(np.arange(2 * SR) < SR, 0.1, 0.5)
    env = energy_envelope(_tone(2.0, 150, amp=amp), SR, fps=25)
    assert env.shape == (50,) and env.max() == 0.0
    assert abs(np.median(env[30:]) - np.median(env[:20]) - 20 * np.log10(5)) < 0.5
    env = energy_envelope(np.zeros(SR, np.float32), SR, 30, num_frames=40)
    assert env.shape == (40,) and (env == -60).all()


def test_onsets_of_tone_bursts():
    wav = np.zeros(3 * SR, np.float32)
    starts = np.array([0.3, 0.9, 1.45, 2.2])
    for s in starts:
        i = int(s * SR)
        wav[i : i + int(0.2 * SR)] = _tone(0.2, 180.0, amp=0.4)
    onsets = detect_onsets(wav, SR)
    assert len(onsets) == len(starts) and np.abs(onsets - starts).max() < 0.03


# -- measures ------------------------------------------------------------------------------
def _translating(T=60, fps=30.0, v=(0.6, 0.0, 0.8)):
    trans = np.outer(np.arange(T) / fps, v) + [0, 0.9, 0]
    return Motion(np.zeros((T, 24, 3)), trans, fps)


def test_hand_speed_of_a_gliding_body():
    m = _translating()
    assert np.allclose(hand_speed(m), 1.0, atol=1e-4)  # |(0.6, 0, 0.8)| m/s
    assert hand_speed(m, reduce="none").shape == (60, 2)
    with pytest.raises(MotionValueError):
        hand_speed(m, reduce="median")


def test_lagged_correlation_finds_the_shift():
    x = rng.normal(size=300)
    y = np.roll(x, 3) + 0.1 * rng.normal(size=300)  # motion follows speech by 3 frames
    c = lagged_correlation(x, y, fps=25, max_lag=6)
    assert c.lag_frames == 3 and abs(c.lag_s - 0.12) < 1e-9 and c.r > 0.95 and c.r_zero_lag < 0.3
    assert lagged_correlation(np.ones(50), y[:50], 25, 2).r == 0.0
    m = _translating(T=300)
    with pytest.raises(MotionValueError, match="300 motion frames"):
        speech_motion_correlation(np.zeros(200), m)


def test_beat_alignment_score():
    fps = 25.0
    t = np.arange(250) / fps
    speed = np.abs(np.sin(np.pi * t))  # minima (beats) at every whole second
    beats = motion_beats(speed, fps)
    assert np.allclose(beats, np.arange(1, 10))
    m = _translating(T=250, fps=fps)
    assert beat_alignment_score([2.0, 5.0], m, beats_s=beats) == pytest.approx(1.0)
    d = np.array([0.05, 0.5])
    expect = np.exp(-(d**2) / (2 * 0.05**2)).mean()
    assert beat_alignment_score([3.05, 6.5], m, beats_s=beats) == pytest.approx(expect)
    assert beat_alignment_score([3.0], m, beats_s=np.zeros(0)) == 0.0
    with pytest.raises(MotionValueError, match="no speech onset"):
        beat_alignment_score([50.0], m, beats_s=beats)
