"""The add-on's logic that needs no Blender (poses on the rig: ``rig.py``): it imports without ``bpy`` (plain Python 3.10+,
no numpy), so ``tests/test_blender_addon.py`` tests it outside Blender.

* **Which Python** (``resolve_python``): the preference may name a Python executable or a
  virtual environment's folder (``.venv``), whose ``bin/python`` (``Scripts\\python.exe``
  on Windows) is taken.
* **Command lines** (``train_args``, ``resume_args``, ``sample_args``, ``restyle_args``,
  ``bridge_args``): argument lists for ``python -m mrlib ...`` and for the add-on's
  ``bridge.py``, which runs under that same Python; never a shell string.
* **Progress and errors** (``parse_line``): the command line's output with
  ``MRLIB_PROGRESS=lines``, one line per finished task (``block 2/4 (levels 3-4): 400/400
  in 51.2 s, D=-0.31``), its one-line errors (``error: <file>: <problem>``) and warnings.
* **Child processes** (``Job``, ``Pipeline``): a command run in a subprocess, its output
  read by threads into a queue that ``poll()`` drains (Blender calls it from a timer, so
  its UI never waits); ``cancel()`` sends an interrupt (mrlib's training then saves its
  checkpoint), then terminates, then kills a child that does not stop.
* **Joint maps** (``read_joint_map``, ``check_joint_map``): ``{SMPL joint: bone}`` files
  as ``mrlib info --write-map`` writes them, checked against an armature's bone names.
"""

from __future__ import annotations

import json
import os
import queue
import re
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

PRESETS = ("demo", "preview", "tutorial", "paper")
SMPL_JOINTS = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_hand", "right_hand",
)  # fmt: skip
BRIDGE = Path(__file__).with_name("bridge.py")


class SetupError(Exception):
    """Something the user must fix before a command can run (a wrong path, no clips)."""


# -- which Python ---------------------------------------------------------------------------
def resolve_python(setting: str) -> str:
    """The Python executable that ``setting`` names: the executable itself, or a virtual
    environment's folder (or the repository holding ``.venv``). Raises ``SetupError``."""
    text = os.path.expanduser(str(setting or "").strip())
    if not text:
        raise SetupError(
            "set the Python that has mrlib installed (Edit > Preferences > Add-ons > mrlib: "
            "the path to its .venv or to its python)"
        )
    path = Path(text)
    if path.is_dir():
        for base in (path, path / ".venv", path / "venv"):
            for name in ("bin/python3", "bin/python", "Scripts/python.exe"):
                if (base / name).is_file():
                    return str(base / name)
        raise SetupError(f"{path}: no bin/python (nor Scripts\\python.exe) in this folder")
    if not path.is_file():
        raise SetupError(f"{path}: no such file or folder")
    if not os.access(path, os.X_OK):
        raise SetupError(f"{path}: not an executable")
    return str(path)


def child_env(base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of a child process: Blender's, less what would make another Python
    read Blender's own modules, with mrlib's progress as one line per task."""
    env = dict(os.environ if base is None else base)
    for name in ("PYTHONHOME", "PYTHONPATH", "PYTHONSTARTUP", "PYTHONNOUSERSITE"):
        env.pop(name, None)
    env["MRLIB_PROGRESS"] = "lines"
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONIOENCODING"] = "utf-8"
    return env


# -- command lines ----------------------------------------------------------------------------
def mrlib_command(python: str, *args: str) -> list[str]:
    """``[python, "-m", "mrlib", *args]``."""
    return [python, "-m", "mrlib", *[str(a) for a in args]]


def _threads(threads: int | None) -> list[str]:
    return ["--threads", str(int(threads))] if threads else []


def train_args(
    clips: Sequence[str | Path],
    labels: Sequence[str],
    out: str | Path,
    *,
    preset: str = "demo",
    iterations: int | Sequence[int] | None = None,
    levels: int | None = None,
    seed: int | None = None,
    joint_map: str | Path | None = None,
    accept_retarget_error: bool = False,
    overwrite: bool = False,
    threads: int | None = None,
) -> list[str]:
    """``mrlib train`` arguments: one label per clip (``--labels``), a preset, ``--out``;
    ``iterations`` (one count or one per block) and ``levels`` override the preset's."""
    if not clips:
        raise SetupError("no clips to train on: add armature actions to the clip list")
    if len(labels) != len(clips):
        raise SetupError(f"{len(clips)} clips but {len(labels)} labels")
    bad = [i + 1 for i, lab in enumerate(labels) if not str(lab).strip()]
    if bad:
        raise SetupError(f"clip {bad[0]} has no label")
    if preset not in PRESETS:
        raise SetupError(f"preset must be one of {', '.join(PRESETS)}, got {preset!r}")
    args = ["train", *[str(c) for c in clips], "--labels", *[str(lab) for lab in labels]]
    args += ["--preset", preset, "--out", str(out)]
    if iterations:
        its = [iterations] if isinstance(iterations, int) else list(iterations)
        args += ["--iterations", ",".join(str(int(i)) for i in its)]
    if levels:
        args += ["--levels", str(int(levels))]
    if seed is not None:
        args += ["--seed", str(int(seed))]
    if joint_map:
        args += ["--joint-map", str(joint_map)]
    if accept_retarget_error:
        args.append("--accept-retarget-error")
    if overwrite:
        args.append("--overwrite")
    return args + _threads(threads)


def resume_args(checkpoint: str | Path, *, threads: int | None = None) -> list[str]:
    """``mrlib train --resume CHECKPOINT --out FOLDER`` (the checkpoint's own folder)."""
    checkpoint = Path(checkpoint)
    return ["train", "--resume", str(checkpoint), "--out", str(checkpoint.parent)] + _threads(
        threads
    )


def crossover_specs(coarse: str, fine: str, level: int, num_levels: int) -> list[str]:
    """``--crossover`` values: ``coarse`` drives levels 1..``level``, ``fine`` the rest."""
    if num_levels < 2:
        raise SetupError(
            f"a crossover needs a model of 2 or more levels, this one has {num_levels}"
        )
    if not 1 <= level < num_levels:
        raise SetupError(f"crossover level must be in 1..{num_levels - 1}, got {level}")
    return [f"{coarse}:1-{level}", f"{fine}:{level + 1}-{num_levels}"]


@dataclass(frozen=True)
class Condition:
    """What drives generation: one ``label``; a crossover (``coarse`` label on levels
    1..``level``, ``fine`` on the others, of ``num_levels``); or a ``blend`` of two labels
    with ``weight`` of the second."""

    mode: str = "label"  # "label", "crossover" or "blend"
    label: str = ""
    coarse: str = ""
    fine: str = ""
    level: int = 1
    num_levels: int = 0
    weight: float = 0.5

    def args(self) -> list[str]:
        if self.mode == "label":
            return ["--label", self.label] if self.label else []
        if self.mode == "crossover":
            if not (self.coarse and self.fine):
                raise SetupError("a crossover needs a coarse and a fine label")
            return ["--crossover", *crossover_specs(self.coarse, self.fine, self.level, self.num_levels)]  # fmt: skip
        if self.mode == "blend":
            if not (self.coarse and self.fine):
                raise SetupError("a blend needs two labels")
            if not 0.0 <= self.weight <= 1.0:
                raise SetupError(f"blend weight must be in 0..1, got {self.weight:g}")
            return ["--blend", self.coarse, self.fine, f"{self.weight:g}"]
        raise SetupError(f"unknown condition mode {self.mode!r}")


def sample_args(
    checkpoint: str | Path,
    out: str | Path,
    condition: Condition,
    *,
    seconds: float | None = None,
    seed: int = 0,
    loop: bool = False,
    path: str | Path | None = None,
    keyframes: str | Path | None = None,
    prefix: str | Path | None = None,
    raw: bool = False,
    overwrite: bool = True,
    threads: int | None = None,
) -> list[str]:
    """``mrlib sample`` arguments for one sample (``--num 1``) written to ``out``: at most
    one of a loop, a ``path`` CSV, a ``keyframes`` file (``--keyframes``, needs
    ``seconds``) and a ``prefix`` motion to continue (``--continue``, ``seconds`` more)."""
    chosen = [name for name, on in (("a loop", loop), ("a path", path),
                                    ("timeline keyframes", keyframes),
                                    ("continuing the action", prefix)) if on]  # fmt: skip
    if len(chosen) > 1:
        raise SetupError(f"{' and '.join(chosen)} cannot be combined: choose one")
    if (keyframes or prefix) and not (seconds and seconds > 0):
        what = "keyframes need" if keyframes else "continuing needs"
        raise SetupError(f"{what} a length in seconds")
    args = ["sample", str(checkpoint), *condition.args()]
    if loop:
        args.append("--loop")
    if path:
        args += ["--path", str(path)]
    if keyframes:
        args += ["--keyframes", str(keyframes)]
    if prefix:
        args += ["--continue", str(prefix)]
    if seconds:
        args += ["--seconds", f"{float(seconds):g}"]
    args += ["--seed", str(int(seed)), "--num", "1", "--out", str(out)]
    if raw:
        args.append("--raw")
    if overwrite:
        args.append("--overwrite")
    return args + _threads(threads)


def restyle_args(
    checkpoint: str | Path,
    clip: str | Path,
    label: str,
    out: str | Path,
    *,
    level: int | None = None,
    keep: str = "coarse",
    seed: int = 0,
    joint_map: str | Path | None = None,
    overwrite: bool = True,
    threads: int | None = None,
    up_axis: str | None = None,
) -> list[str]:
    """``mrlib restyle`` arguments: ``clip`` (a BVH of the rig) towards ``label``, read with
    ``up_axis`` when given (the rig's, :func:`axes_args`), else mrlib's detection."""
    if not label:
        raise SetupError("restyle needs a label")
    if keep not in ("coarse", "detail"):
        raise SetupError(f"keep must be 'coarse' or 'detail', got {keep!r}")
    args = ["restyle", str(checkpoint), str(clip), "--label", label, "--keep", keep]
    if level:
        args += ["--level", str(int(level))]
    args += ["--seed", str(int(seed)), "--out", str(out)]
    if joint_map:
        args += ["--joint-map", str(joint_map)]
    if up_axis:
        args += ["--up-axis", str(up_axis)]
    if overwrite:
        args.append("--overwrite")
    return args + _threads(threads)


def bridge_args(python: str, command: str, *args: str | Path) -> list[str]:
    """``[python, bridge.py, command, *args]``: the add-on's helper, run by mrlib's Python."""
    return [python, str(BRIDGE), command, *[str(a) for a in args]]


def onto_rig_args(
    python: str,
    rig_bvh: str | Path,
    motion: str | Path,
    out_json: str | Path,
    *,
    out_bvh: str | Path | None = None,
    joint_map: str | Path | None = None,
) -> list[str]:
    """The bridge's ``onto-rig``: ``motion`` (an SMPL .npz mrlib wrote) as rotations of the
    rig in ``rig_bvh`` (a clip of it), to ``out_json`` (and a BVH of the rig)."""
    args = [rig_bvh, motion, "--out", out_json]
    if out_bvh:
        args += ["--bvh", out_bvh]
    if joint_map:
        args += ["--joint-map", joint_map]
    return bridge_args(python, "onto-rig", *args)


def axes_args(
    python: str, rig_bvh: str | Path, out: str | Path, *, joint_map: str | Path | None = None
) -> list[str]:
    """The bridge's ``axes``: the up axis mrlib reads ``rig_bvh`` in, as JSON ``{"up_axis"}``
    (read back by :func:`read_up_axis`)."""
    args = [rig_bvh, "--out", out]
    if joint_map:
        args += ["--joint-map", joint_map]
    return bridge_args(python, "axes", *args)


def read_up_axis(path: str | Path) -> str:
    """The ``up_axis`` the bridge's ``axes`` wrote to ``path``."""
    axis = json.loads(Path(path).read_text(encoding="utf-8")).get("up_axis")
    if axis not in ("x", "y", "z", "-x", "-y", "-z"):
        raise SetupError(f"{path}: no up axis in it")
    return axis


def read_args(
    python: str, rig_bvh: str | Path, out: str | Path, *, joint_map: str | Path | None = None
) -> list[str]:
    """The bridge's ``read``: a clip of the rig as mrlib reads it (SMPL parameters, .npz)."""
    args = [rig_bvh, "--out", out]
    if joint_map:
        args += ["--joint-map", joint_map]
    return bridge_args(python, "read", *args)


@dataclass(frozen=True)
class TimelineKey:
    """A keyed frame of the timeline: ``index`` into the clip exported from the action's
    first frame, ``seconds`` after the frame the generated motion starts at."""

    index: int
    seconds: float


def timeline_keys(
    keyed: Iterable[float], first: int, start: float, scene_fps: float
) -> list[TimelineKey]:
    """The keys of frames ``keyed`` (scene frames with a key on any bone; sub-frame keys
    taken at the nearest frame) of an action exported from scene frame ``first``, for a
    motion starting at scene frame ``start``: the keys before ``start`` are left out."""
    if scene_fps <= 0:
        raise SetupError(f"the scene's frame rate must be positive, got {scene_fps:g}")
    frames = sorted({int(round(float(f))) for f in keyed})
    out = [
        TimelineKey(f - first, (f - start) / scene_fps) for f in frames if f >= start and f >= first
    ]
    if not out:
        raise SetupError(
            f"no keyframes at or after the start frame {start:g}: key the armature's pose "
            "on the timeline first"
        )
    return out


def keyframe_seconds(keys: Sequence[TimelineKey], seconds: float, scene_fps: float) -> float:
    """The length to generate: ``seconds`` (0: up to the last key, one frame past it); a
    length that ends before the last key is refused."""
    need = keys[-1].seconds + 1.0 / scene_fps
    if not seconds:
        return need
    if seconds < need - 1e-9:
        raise SetupError(
            f"the last keyframe is {keys[-1].seconds:.3g} s after the start frame: ask for at "
            f"least {need:.3g} s, or 0 for that"
        )
    return float(seconds)


def keyframes_args(
    python: str,
    rig_bvh: str | Path,
    checkpoint: str | Path,
    keys: Sequence[TimelineKey],
    out: str | Path,
    *,
    joint_map: str | Path | None = None,
) -> list[str]:
    """The bridge's ``keyframes``: the poses of ``rig_bvh`` at ``keys`` as a keyframe file
    of ``mrlib sample --keyframes`` (frames at the model's rate)."""
    args = [rig_bvh, checkpoint, "--frames", ",".join(str(k.index) for k in keys),
            "--times", ",".join(f"{k.seconds:.6f}" for k in keys), "--out", out]  # fmt: skip
    if joint_map:
        args += ["--joint-map", joint_map]
    return bridge_args(python, "keyframes", *args)


# -- progress and error lines -------------------------------------------------------------------
_TASK = re.compile(
    r"^(?:(?P<desc>.+?): )?(?P<count>\d+(?:\.\d+)?(?:/\d+(?:\.\d+)?)?|\d+%)"
    r" in (?P<seconds>\d+(?:\.\d+)?) s(?:, (?P<post>.*))?$"
)
_PART = re.compile(r"^(?:block|level|\[)\s*(?P<k>\d+)/(?P<n>\d+)")
_ERROR = re.compile(r"^(?:\S*mrlib(?: [\w-]+)?: )?error: (?P<text>.*)$")
_WARNING = re.compile(r"^warning: (?P<text>.*)$")


@dataclass(frozen=True)
class Event:
    """One line of a command's output, read.

    ``kind``: ``"task"`` (a finished task: ``desc``, ``seconds``, and ``fraction``, the
    share of the whole command done when the task says it is part k of n, e.g. a
    training block), ``"error"``, ``"warning"`` or ``"info"`` (anything else)."""

    kind: str
    text: str
    desc: str = ""
    seconds: float | None = None
    fraction: float | None = None
    stream: str = "stderr"


def parse_line(line: str, stream: str = "stderr") -> Event:
    """Read one output line (see ``Event``)."""
    line = line.rstrip("\r\n")
    text = line.strip()
    m = _ERROR.match(text)
    if m:
        return Event("error", m.group("text").strip(), stream=stream)
    m = _WARNING.match(text)
    if m:
        return Event("warning", m.group("text").strip(), stream=stream)
    m = _TASK.match(text)
    if m:
        desc = (m.group("desc") or "").strip()
        fraction = None
        part = _PART.match(desc)
        if part and int(part.group("n")) > 0:
            fraction = min(1.0, int(part.group("k")) / int(part.group("n")))
        return Event("task", text, desc, float(m.group("seconds")), fraction, stream)
    return Event("info", text, stream=stream)


def error_text(events: Iterable[Event], returncode: int | None, stderr_tail: Sequence[str]) -> str:
    """The one line to show for a failed command: its last ``error:`` line, else the last
    line it printed on standard error, else its exit status."""
    errors = [e.text for e in events if e.kind == "error"]
    if errors:
        return errors[-1]
    tail = [t.strip() for t in stderr_tail if t.strip()]
    if tail:
        return tail[-1]
    return f"the command stopped with exit status {returncode}"


# -- child processes -----------------------------------------------------------------------------
class Job:
    """One command in a child process, read without blocking.

    ``start()`` launches it; ``poll()`` returns the ``Event`` s of the lines printed since the
    last call and updates ``fraction``, ``status`` and, once it ended, ``returncode``;
    ``cancel()`` asks it to stop (an interrupt, then ``terminate`` after ``grace`` seconds,
    then ``kill``), and ``poll()`` carries that through without waiting. ``wait()`` polls
    until the end (headless use)."""

    def __init__(self, argv: Sequence[str], *, name: str = "mrlib", cwd: str | None = None,
                 env: dict[str, str] | None = None, grace: float = 10.0) -> None:  # fmt: skip
        self.argv = [str(a) for a in argv]
        self.name, self.cwd, self.grace = name, cwd, grace
        self.env = child_env() if env is None else env
        self.proc: subprocess.Popen | None = None
        self.lines: queue.Queue[tuple[str, str | None]] = queue.Queue()
        self.events: list[Event] = []
        self.stderr_tail: list[str] = []
        self.fraction = 0.0
        self.status = f"{name}: starting"
        self.returncode: int | None = None
        self.cancelled = False
        self.started = 0.0
        self._stop_at: float | None = None
        self._step = 0
        self._open_streams = 0

    # life cycle
    def start(self) -> Job:
        kw: dict = {}
        if os.name == "nt":
            kw["creationflags"] = subprocess.CREATE_NEW_PROCESS_GROUP  # type: ignore[attr-defined]
        else:
            kw["start_new_session"] = True  # Ctrl+C in Blender's terminal stays Blender's
        self.started = time.monotonic()
        try:
            self.proc = subprocess.Popen(
                self.argv, cwd=self.cwd, env=self.env, stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, encoding="utf-8",
                errors="replace", bufsize=1, **kw,
            )  # fmt: skip
        except OSError as e:
            raise SetupError(f"cannot run {self.argv[0]}: {e.strerror or e}") from None
        self._open_streams = 2
        for stream, pipe in (("stdout", self.proc.stdout), ("stderr", self.proc.stderr)):
            threading.Thread(target=self._read, args=(stream, pipe), daemon=True).start()
        self.status = f"{self.name}: running"
        return self

    def _read(self, stream: str, pipe) -> None:
        try:
            for line in pipe:
                self.lines.put((stream, line))
        except (OSError, ValueError):
            pass
        finally:
            self.lines.put((stream, None))

    @property
    def running(self) -> bool:
        return self.proc is not None and self.returncode is None

    @property
    def done(self) -> bool:
        return self.returncode is not None

    @property
    def ok(self) -> bool:
        return self.returncode == 0 and not self.cancelled

    @property
    def error(self) -> str | None:
        """The one-line error of a failed command (None while running, or on success)."""
        if not self.done or self.ok:
            return None
        if self.cancelled:
            return f"{self.name}: cancelled"
        return error_text(self.events, self.returncode, self.stderr_tail)

    def elapsed(self) -> float:
        return time.monotonic() - self.started if self.started else 0.0

    def poll(self) -> list[Event]:
        """New events since the last call; never blocks."""
        new: list[Event] = []
        while True:
            try:
                stream, line = self.lines.get_nowait()
            except queue.Empty:
                break
            if line is None:
                self._open_streams -= 1
                continue
            if not line.strip():
                continue
            event = parse_line(line, stream)
            new.append(event)
            if stream == "stderr":
                self.stderr_tail = (self.stderr_tail + [line.rstrip()])[-20:]
            if event.kind == "task":
                if event.fraction is not None:
                    self.fraction = max(self.fraction, event.fraction)
                self.status = f"{self.name}: {event.desc or event.text}"
            elif event.kind == "info" and event.stream == "stdout":
                self.status = f"{self.name}: {event.text}"[:200]
        self.events += new
        if self.proc is not None and self.returncode is None:
            rc = self.proc.poll()
            if rc is not None and self._open_streams <= 0:
                self.returncode = rc
                if rc == 0 and not self.cancelled:
                    self.fraction = 1.0
            elif rc is None and self._stop_at is not None:
                self._escalate()
            elif rc is not None and time.monotonic() - (self._stop_at or self.started) > 30:
                self.returncode = rc  # a grandchild kept the pipes open: stop reading them
        return new

    def cancel(self, grace: float | None = None) -> None:
        """Ask the child to stop: an interrupt now (mrlib saves a training checkpoint and
        exits), ``terminate`` after ``grace`` seconds, ``kill`` after twice that."""
        if self.proc is None or self.returncode is not None or self.cancelled:
            return
        self.cancelled = True
        self.grace = self.grace if grace is None else grace
        self.status = f"{self.name}: cancelling"
        self._stop_at = time.monotonic()
        self._step = 0
        self._escalate()

    def _escalate(self) -> None:
        assert self.proc is not None and self._stop_at is not None
        waited = time.monotonic() - self._stop_at
        try:
            if self._step == 0:
                if os.name == "nt":
                    self.proc.send_signal(signal.CTRL_BREAK_EVENT)  # type: ignore[attr-defined]
                else:
                    self.proc.send_signal(signal.SIGINT)
                self._step = 1
            elif self._step == 1 and waited >= self.grace:
                self.proc.terminate()
                self._step = 2
            elif self._step == 2 and waited >= 2 * self.grace:
                self.proc.kill()
                self._step = 3
        except OSError:  # already gone
            pass

    def wait(self, timeout: float | None = None, on_event: Callable[[Event], None] | None = None,
             interval: float = 0.05) -> int:  # fmt: skip
        """Poll until the command ends (``timeout`` seconds: cancel it); its exit status."""
        if self.proc is None:
            self.start()
        _drive(self, lambda: self.done, lambda: self.cancel(grace=2.0), timeout, interval, on_event)
        for e in self.poll():  # what the last reads queued
            if on_event is not None:
                on_event(e)
        return int(self.returncode or 0)


def _drive(runner, done: Callable[[], bool], cancel: Callable[[], None], timeout: float | None,
           interval: float, on_event: Callable[[Event], None] | None) -> None:  # fmt: skip
    """Poll ``runner`` (a ``Job`` or ``Pipeline``) until ``done()``, handing its events to
    ``on_event``; past ``timeout`` seconds ``cancel()`` it once."""
    end = None if timeout is None else time.monotonic() + timeout
    while not done():
        for e in runner.poll():
            if on_event is not None:
                on_event(e)
        if end is not None and time.monotonic() > end and not runner.cancelled:
            cancel()
        time.sleep(interval)


@dataclass
class Step:
    """One command of a ``Pipeline``: ``argv`` (or a function returning it, called when
    the step starts, so it can use what the steps before it wrote), its share of the
    progress bar, and ``after``, called (on Blender's thread) once it succeeded."""

    name: str
    argv: Sequence[str] | Callable[[], Sequence[str]]
    weight: float = 1.0
    after: Callable[[], None] | None = None


@dataclass
class Pipeline:
    """Commands run one after another; stops at the first that fails or is cancelled.
    ``poll()`` drives it (never blocks); ``fraction`` and ``status`` describe it;
    ``error`` is the failed step's one-line error."""

    steps: list[Step]
    name: str = "mrlib"
    cwd: str | None = None
    env: dict[str, str] | None = None
    index: int = 0
    job: Job | None = None
    error: str | None = None
    finished: bool = False
    cancelled: bool = False
    warnings: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)

    @property
    def fraction(self) -> float:
        total = sum(s.weight for s in self.steps) or 1.0
        done = sum(s.weight for s in self.steps[: self.index])
        if self.finished:
            return 1.0 if self.error is None and not self.cancelled else min(1.0, done / total)
        current = self.job.fraction * self.steps[self.index].weight if self.job else 0.0
        return min(1.0, (done + current) / total)

    @property
    def status(self) -> str:
        if self.finished:
            return f"{self.name}: " + (
                "cancelled" if self.cancelled else "failed" if self.error else "done"
            )
        step = self.steps[self.index]
        text = self.job.status if self.job else f"{step.name}: starting"
        seconds = self.job.elapsed() if self.job else 0.0
        return f"{self.name} [{self.index + 1}/{len(self.steps)}] {text} ({seconds:.0f} s)"

    def poll(self) -> list[Event]:
        if self.finished:
            return []
        step = self.steps[self.index]
        try:
            if self.job is None:
                argv = step.argv() if callable(step.argv) else step.argv
                self.job = Job(argv, name=step.name, cwd=self.cwd, env=self.env).start()
            events = self.job.poll()
            self.warnings += [e.text for e in events if e.kind == "warning"]
            if self.job.done:
                if self.job.cancelled or self.cancelled:
                    self.cancelled, self.finished = True, True
                elif not self.job.ok:
                    self.error, self.finished = self.job.error, True
                else:
                    if step.after is not None:
                        step.after()
                    self.index += 1
                    self.job = None
                    self.finished = self.index >= len(self.steps)
        except SetupError as e:
            self.error, self.finished = str(e), True
            return []
        except Exception as e:  # an after() that failed: one line, like the command line
            self.error, self.finished = f"{step.name}: {type(e).__name__}: {e}", True
            return []
        return events

    def cancel(self) -> None:
        self.cancelled = True
        if self.job is not None:
            self.job.cancel()
        else:
            self.finished = True

    def wait(self, timeout: float | None = None, interval: float = 0.05,
             on_event: Callable[[Event], None] | None = None) -> bool:  # fmt: skip
        """Run to the end (headless); True when every step succeeded."""
        _drive(self, lambda: self.finished, self.cancel, timeout, interval, on_event)
        return self.error is None and not self.cancelled


# -- joint maps, clips and paths ---------------------------------------------------------------------
def read_joint_map(path: str | Path) -> dict[str, str]:
    """A joint map file: ``{"map": {smpl: bone}}`` (mrlib's shipped and written maps) or a
    plain ``{smpl: bone}``."""
    path = Path(path)
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise SetupError(f"{path}: cannot read the joint map ({e})") from None
    mapping = d.get("map", d) if isinstance(d, dict) else None
    if not isinstance(mapping, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in mapping.items()
    ):
        raise SetupError(f"{path}: a joint map is an object {{smpl_joint: bone}}")
    unknown = sorted(set(mapping) - set(SMPL_JOINTS))
    if unknown:
        raise SetupError(f"{path}: not SMPL joints: {', '.join(unknown)}")
    return dict(mapping)


def check_joint_map(mapping: dict[str, str], bones: Iterable[str]) -> list[str]:
    """The bones ``mapping`` names that are not among ``bones`` (empty: it fits)."""
    have = set(bones)
    return sorted({b for b in mapping.values() if b not in have})


def bvh_unsafe_names(names: Iterable[str]) -> list[str]:
    """Bone names a BVH file cannot hold (whitespace, braces; empty)."""
    return [n for n in names if not n or re.search(r"[\s{}]", n)]


def safe_file_stem(text: str, fallback: str = "clip") -> str:
    """``text`` as a file name stem: letters, digits, ``-_.`` (others become ``_``)."""
    stem = re.sub(r"[^\w.-]+", "_", str(text), flags=re.ASCII).strip("._")
    return stem[:80] or fallback


def unique_stems(texts: Sequence[str]) -> list[str]:
    """``safe_file_stem`` of each, repeated ones numbered."""
    seen: dict[str, int] = {}
    out = []
    for t in texts:
        s = safe_file_stem(t)
        n = seen.get(s.lower(), 0)
        seen[s.lower()] = n + 1
        out.append(s if n == 0 else f"{s}_{n + 1}")
    return out


def path_csv(points: Iterable[Sequence[float]]) -> str:
    """A ``mrlib sample --path`` CSV from ground points ``(x, y)`` of Blender (Z up,
    metres): mrlib's ground plane is ``(x, z)`` with Y up, and the BVH importer's turn
    (``-Y`` forward) makes mrlib's ``z`` Blender's ``-y``."""
    rows = ["x,z"]
    for p in points:
        rows.append(f"{float(p[0]):.6f},{-float(p[1]):.6f}")
    if len(rows) < 3:
        raise SetupError("a path needs at least two points")
    return "\n".join(rows) + "\n"


def find_outputs(folder: str | Path, suffix: str = ".npz") -> list[Path]:
    """The files of ``folder`` ending in ``suffix``, sorted by name."""
    return sorted(p for p in Path(folder).glob(f"*{suffix}") if p.is_file())


def checkpoint_levels(checkpoint: str | Path) -> int | None:
    """The number of pyramid levels from ``checkpoint.pt.json`` beside a checkpoint."""
    try:
        d = json.loads(Path(str(checkpoint) + ".json").read_text(encoding="utf-8"))
        return int(d["model"]["num_levels"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def split_labels(text: str) -> list[str]:
    """Labels stored as one comma-separated string."""
    return [t.strip() for t in str(text or "").split(",") if t.strip()]
