"""Speak one text with ``libespeak-ng`` and write the samples to standard output.

Run as a script by :mod:`mrlib.speech.espeak`, one process per text: the library keeps
state between utterances (the same text spoken twice in one process gives slightly
different samples), so a fresh process, with the library's random numbers seeded, is what
makes synthesis reproducible. Standard
library only, so the process starts in milliseconds.

Usage: ``python _espeak_worker.py LIB DATA VOICE SPEED PITCH SSML < text``; writes the
sample rate as 4 little-endian bytes, then int16 mono samples. Exit status 3: the library
did not initialise; 4: unknown voice; 5: synthesis failed.
"""

import ctypes
import sys

AUDIO_OUTPUT_SYNCHRONOUS = 2
INITIALIZE_DONT_EXIT = 0x8000  # report errors instead of calling exit()
RATE, PITCH = 1, 3
CHARS_UTF8, SSML, ENDPAUSE = 1, 0x10, 0x1000
POS_CHARACTER = 1
SEED = 1  # of eSpeak NG's random numbers (the breath noise of some voice variants)


class Voice(ctypes.Structure):
    """``espeak_VOICE`` of eSpeak NG's ``speak_lib.h``."""

    _fields_ = [
        ("name", ctypes.c_char_p),
        ("languages", ctypes.c_char_p),
        ("identifier", ctypes.c_char_p),
        ("gender", ctypes.c_ubyte),
        ("age", ctypes.c_ubyte),
        ("variant", ctypes.c_ubyte),
        ("xx1", ctypes.c_ubyte),
        ("score", ctypes.c_int),
        ("spare", ctypes.c_void_p),
    ]


CALLBACK = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.c_void_p
)


def main(argv: list[str]) -> int:
    lib_path, data_path, voice, speed, pitch, ssml = argv
    text = sys.stdin.buffer.read()
    lib = ctypes.CDLL(lib_path)
    lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
    lib.espeak_SetSynthCallback.argtypes = [CALLBACK]
    lib.espeak_SetSynthCallback.restype = None
    lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
    lib.espeak_SetVoiceByProperties.argtypes = [ctypes.POINTER(Voice)]
    lib.espeak_GetCurrentVoice.restype = ctypes.POINTER(Voice)
    lib.espeak_Synth.argtypes = [
        ctypes.c_char_p,
        ctypes.c_size_t,
        ctypes.c_uint,
        ctypes.c_int,
        ctypes.c_uint,
        ctypes.c_uint,
        ctypes.c_void_p,
        ctypes.c_void_p,
    ]
    rate = lib.espeak_Initialize(
        AUDIO_OUTPUT_SYNCHRONOUS, 0, data_path.encode(), INITIALIZE_DONT_EXIT
    )
    if rate <= 0:
        return 3
    chunks = []

    def collect(wav, n, events):
        if n > 0:
            chunks.append(ctypes.string_at(wav, 2 * n))
        return 0

    callback = CALLBACK(collect)
    lib.espeak_SetSynthCallback(callback)
    # a voice file's name ("en-us", "gmw/en", "en-us+f3"), else a language code, with
    # an optional variant ("en-gb+m3"): the language picks the voice, then the variant
    # is applied to that voice's file
    if lib.espeak_SetVoiceByName(voice.encode()) != 0:
        language, _, variant = voice.partition("+")
        if lib.espeak_SetVoiceByProperties(ctypes.byref(Voice(languages=language.encode()))) != 0:
            return 4
        if variant:
            current = lib.espeak_GetCurrentVoice().contents.identifier
            if lib.espeak_SetVoiceByName(current + b"+" + variant.encode()) != 0:
                return 4
    lib.espeak_SetParameter(RATE, int(speed), 0)
    lib.espeak_SetParameter(PITCH, int(pitch), 0)
    buf = text + b"\0"
    flags = CHARS_UTF8 | ENDPAUSE | (SSML if ssml == "1" else 0)
    # The voice variants with breath (en-us+f3, en-gb-x-rp+f2) add noise from eSpeak NG's
    # own random numbers, seeded from the clock: a fixed seed makes every run the same.
    if hasattr(lib, "espeak_ng_SetRandSeed"):
        lib.espeak_ng_SetRandSeed(ctypes.c_long(SEED))
    if lib.espeak_Synth(buf, len(buf), 0, POS_CHARACTER, 0, flags, None, None) != 0:
        return 5
    lib.espeak_Synchronize()
    out = sys.stdout.buffer
    out.write(int(rate).to_bytes(4, "little"))
    out.write(b"".join(chunks))
    out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
