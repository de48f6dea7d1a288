"""Text to speech with eSpeak NG, from pip alone.

The synthetic co-speech set (``mrlib.speech.synthetic``) speaks its sentences with eSpeak NG,
a formant synthesiser. Two back ends give the same voices:

- ``"library"``: ``libespeak-ng`` and its voice data as shipped in the
  ``espeakng-loader`` wheel (a dependency of ``mrlib[speech]``), called through
  ``ctypes``. No system package is needed, and every machine runs the same eSpeak
  build (the one pinned in ``constraints.txt``), so the synthetic corpus is the same
  everywhere.
- ``"program"``: an ``espeak-ng`` program on ``PATH`` (Debian's ``espeak-ng``, Homebrew,
  conda-forge), through its command line.

``backend="auto"`` takes the library when the wheel is installed, else the program.
The library speaks in a short-lived child process (``_espeak_worker.py``, standard
library only, ~20 ms a text): it keeps state between utterances, so the same text
spoken twice in one process comes out slightly different, while a fresh process with
eSpeak NG's random numbers seeded (they add the breath noise of the female variants,
``en-us+f3``, and are seeded from the clock otherwise) gives the same samples every time.
The program cannot be seeded: its breath variants differ from run to run.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from mrlib.errors import MrlibError

__all__ = ["SpeechSynthesisError", "espeak_backend", "espeak_speak"]


class SpeechSynthesisError(MrlibError, RuntimeError):
    """eSpeak NG is missing or failed."""


_INSTALL_HINT = (
    "install the speech extra ('pip install \"mrlib[speech]\"', which brings eSpeak NG as the "
    "espeakng-loader wheel) or an espeak-ng program ('apt-get install espeak-ng', "
    "'brew install espeak-ng', 'conda install -c conda-forge espeak-ng')"
)
_WORKER = Path(__file__).with_name("_espeak_worker.py")
_WORKER_ERRORS = {3: "the library did not initialise", 4: "unknown voice", 5: "synthesis failed"}


def _speak_library(
    text: str, voice: str, speed: int, pitch: int, ssml: bool
) -> tuple[np.ndarray, int]:
    import espeakng_loader

    cmd = [sys.executable, "-I", "-S", str(_WORKER), espeakng_loader.get_library_path()]
    cmd += [
        espeakng_loader.get_data_path(),
        voice,
        str(int(speed)),
        str(int(pitch)),
        str(int(ssml)),
    ]
    proc = subprocess.run(cmd, input=text.encode("utf-8"), capture_output=True, timeout=60)
    if proc.returncode != 0 or len(proc.stdout) < 4:
        why = _WORKER_ERRORS.get(proc.returncode, proc.stderr.decode(errors="replace").strip())
        raise SpeechSynthesisError(f"libespeak-ng failed for voice {voice!r}: {why}")
    sr = int.from_bytes(proc.stdout[:4], "little")
    wav = np.frombuffer(proc.stdout[4 : 4 + (len(proc.stdout) - 4) // 2 * 2], np.int16)
    return wav.astype(np.float32) / 32768.0, sr


def _library_available() -> bool:
    try:
        import espeakng_loader  # noqa: F401
    except ImportError:
        return False
    return True


def espeak_backend(backend: str = "auto") -> str | None:
    """The back end ``espeak_speak`` would use: ``"library"``, ``"program"`` or None when
    neither is installed. ``backend``: ``"auto"``, ``"library"`` or ``"program"``."""
    if backend not in ("auto", "library", "program"):
        raise SpeechSynthesisError(
            f"backend must be 'auto', 'library' or 'program', got {backend!r}"
        )
    if backend in ("auto", "library") and _library_available():
        return "library"
    if backend in ("auto", "program") and shutil.which("espeak-ng") is not None:
        return "program"
    return None


def _speak_program(
    text: str, voice: str, speed: int, pitch: int, ssml: bool
) -> tuple[np.ndarray, int]:
    import soundfile

    exe = shutil.which("espeak-ng")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "speech.wav"
        cmd = [exe, "-v", voice, "-s", str(int(speed)), "-p", str(int(pitch)), "-w", str(out)]
        cmd += ["-m"] if ssml else []
        proc = subprocess.run(cmd + ["--", text], capture_output=True, text=True, timeout=60)
        if proc.returncode != 0 or not out.is_file():
            msg = (proc.stderr or proc.stdout).strip()
            raise SpeechSynthesisError(f"espeak-ng failed for voice {voice!r}: {msg}")
        wav, sr = soundfile.read(str(out), dtype="float32")
    return (wav.mean(1) if wav.ndim == 2 else wav), int(sr)


def espeak_speak(
    text: str,
    voice: str = "en-us",
    speed: int = 160,
    pitch: int = 50,
    *,
    ssml: bool = False,
    backend: str = "auto",
) -> tuple[np.ndarray, int]:
    """``text`` spoken by eSpeak NG: ``((N,) float32 mono in [-1, 1], sample rate)``.

    Args:
        voice: language plus optional variant, e.g. ``"en-us"``, ``"en-gb+m3"``.
        speed: words per minute (80-450); pitch: 0-99.
        ssml: ``text`` is SSML (``<break time="300ms"/>`` and the like).
        backend: see :func:`espeak_backend`.
    Raises:
        SpeechSynthesisError: no back end installed, unknown voice, or no audio.
    """
    if not text.strip():
        raise SpeechSynthesisError("nothing to say: the text is empty")
    which = espeak_backend(backend)
    if which is None:
        raise SpeechSynthesisError(f"eSpeak NG is not available ({backend!r}): {_INSTALL_HINT}")
    if which == "library":
        wav, sr = _speak_library(text, voice, speed, pitch, ssml)
    else:
        wav, sr = _speak_program(text, voice, speed, pitch, ssml)
    if len(wav) == 0:
        raise SpeechSynthesisError(f"eSpeak NG produced no audio for {text!r}")
    return wav, sr
