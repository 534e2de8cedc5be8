"""A helper process that runs the diffusion of the next segment while this one plays the frames.

A segment's reverse diffusion (and its test-time control) is most of a model frame's work, and it is fixed
when it starts, one segment ahead of the frames shown (job_spec.py). With `pipeline=True` a ReactionGroup
sends each such job to one helper Python process and takes the finished latent at the next segment start;
meanwhile the caller's thread only plays frames (FWSR, decoding, foot cleanup). The result is the very same
latent a job run in the caller's process gives (same code, same noise drawn in advance, one thread), so
pipelining changes when the work is done, never the motion.

Why a process and not a thread: the networks are small, so most of their time is Python issuing small torch
ops under the GIL; a thread doing that slowed the caller's frames instead of overlapping them (measured, see
group.py). Why not multiprocessing: its spawn start re-imports the caller's main script in the child (inside
Blender, a user's script); a plain child started with this module's own bootstrap imports nothing else.

The protocol is length-prefixed pickles over the child's stdin/stdout, between this package and its own
child only. Model weights cross as a `torch.save` payload read back with `weights_only=True`. Large scene
maps (distance fields, floor maps, navigation fields) are sent once and then referred to by a token.
Anything that goes wrong with the helper (it cannot start, it dies, a job fails there) makes the jobs run in
the caller's process again: slower, the same motion.
"""
from __future__ import annotations

import atexit
import io
import itertools
import os
import pickle
import queue
import struct
import subprocess
import sys
import threading
import time
import warnings
import weakref
from pathlib import Path
from typing import Any, BinaryIO

import torch

from .distance_field import DistanceField
from .job_spec import JobSpec, run_job
from .navigation import FloorMap, NavigationField

SHARED_TYPES = (DistanceField, FloorMap, NavigationField)   # sent once, then referred to by token
_HEADER = struct.Struct("<Q")
_REPLY_ID = struct.Struct("<q")   # a reply's job id before its pickle (READY_ID: the helper has started)
READY_ID = -1
_PACKAGE = __name__.rpartition(".")[0]          # this package as the caller imported it
_PACKAGE_DIR = str(Path(__file__).resolve().parent)
CHILD_PACKAGE = "model_runtime"                   # the name the helper imports this package under

# The helper's first lines: ignore Ctrl-C (the caller decides when it ends: it ends when the caller's end of its
# pipe closes), take the result channel out of stdout (so a stray print cannot corrupt it),
# see the caller's import path (PyTorch may live in a folder only the caller added), import this package
# from its folder under CHILD_PACKAGE, and serve; then leave without the interpreter's shutdown (its reader thread
# may still hold stdin, which a normal shutdown reports as a fatal error on the shared stderr).
_BOOT = """
import importlib.util, os, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
out = os.fdopen(os.dup(sys.stdout.fileno()), "wb", buffering=0)
os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
extra = [p for p in os.environ.get("REMOGEN_WORKER_PATH", "").split(os.pathsep) if p and p not in sys.path]
sys.path.extend(extra)
folder, parent = sys.argv[1], sys.argv[2]
spec = importlib.util.spec_from_file_location("model_runtime", os.path.join(folder, "__init__.py"),
                                              submodule_search_locations=[folder])
module = importlib.util.module_from_spec(spec)
sys.modules["model_runtime"] = module
spec.loader.exec_module(module)
from model_runtime.job_worker import serve
serve(sys.stdin.buffer, out, parent)
os._exit(0)
"""


class WorkerError(RuntimeError):
    """The helper process cannot run a job (not started, gone, or the job failed there)."""


# ---------------------------------------------------------------------------------------------- framing
def _write(stream: BinaryIO, payload: bytes) -> None:
    data = memoryview(_HEADER.pack(len(payload)) + payload)
    while data:                       # an unbuffered pipe may take part of it at a time
        n = stream.write(data)
        data = data[len(data) if n is None else n:]
    stream.flush()


def _read_exact(stream: BinaryIO, n: int) -> bytes | None:
    chunks, left = [], n
    while left:
        chunk = stream.read(left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _read(stream: BinaryIO) -> bytes | None:
    head = _read_exact(stream, _HEADER.size)
    return None if head is None else _read_exact(stream, _HEADER.unpack(head)[0])


# ---------------------------------------------------------------------------------------------- the helper
class _ChildUnpickler(pickle.Unpickler):
    """Reads the caller's pickles: its package name (a sub-package inside Blender) becomes CHILD_PACKAGE, and
    shared scene maps come from the objects received before."""

    def __init__(self, data: bytes, parent: str, objects: dict) -> None:
        super().__init__(io.BytesIO(data))
        self.parent, self.objects = parent, objects

    def find_class(self, module: str, name: str) -> Any:
        if module == self.parent or module.startswith(self.parent + "."):
            module = CHILD_PACKAGE + module[len(self.parent):]
        return super().find_class(module, name)

    def persistent_load(self, token: Any) -> Any:
        return self.objects[token]


def serve(inp: BinaryIO, out: BinaryIO, parent: str) -> None:
    """The helper's loop: models, shared objects and jobs in; finished latents (or one-line errors) out. Ends
    when the caller says so or its end of the pipe closes."""
    from .checkpoint import model_from_payload
    torch.set_num_threads(1)
    inbox: queue.Queue = queue.Queue()

    def reader() -> None:          # keeps the caller's writes from ever waiting on a busy helper
        while True:
            data = _read(inp)
            inbox.put(data)
            if data is None:
                return

    threading.Thread(target=reader, daemon=True).start()
    models: dict = {}
    objects: dict = {}
    if not _reply(out, READY_ID, ("ready",)):
        return
    while True:
        data = inbox.get()
        if data is None:
            return
        msg = _ChildUnpickler(data, parent, objects).load()
        kind = msg[0]
        if kind == "quit":
            return
        if kind == "model":
            _, key, payload = msg
            state = torch.load(io.BytesIO(payload), weights_only=True, map_location="cpu")
            models[key] = model_from_payload(state).eval()
        elif kind == "forget_model":
            models.pop(msg[1], None)
        elif kind == "object":
            objects[msg[1]] = msg[2]
        elif kind == "forget":
            objects.pop(msg[1], None)
        elif kind == "job":
            _, job_id, key, spec = msg
            try:
                with torch.no_grad():
                    latent = run_job(models[key], spec)
                reply = ("result", job_id, latent)
            except Exception as exc:   # reported to the caller, which runs the job itself
                reply = ("error", job_id, f"{type(exc).__name__}: {exc}")
            if not _reply(out, job_id, reply):
                return


def _reply(out: BinaryIO, job_id: int, msg: tuple) -> bool:
    """Send a message to the caller, its job id first (the caller's reader files it without unpickling it); False
    when the caller is gone (it exited: so does the helper, quietly)."""
    try:
        _write(out, _REPLY_ID.pack(job_id) + pickle.dumps(msg))
        return True
    except (BrokenPipeError, OSError, ValueError):
        return False


# ---------------------------------------------------------------------------------------------- the caller
class _SpecPickler(pickle.Pickler):
    def __init__(self, file: BinaryIO, worker: "JobWorker", root: Any = None) -> None:
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self.worker, self.root = worker, root

    def persistent_id(self, obj: Any) -> Any:
        if obj is not self.root and isinstance(obj, SHARED_TYPES):
            return self.worker._token(obj)
        return None


def pipelinable(model: Any) -> bool:
    """Whether a model's jobs can run in the helper: plain float32 weights (a bf16 or int8 model runs here)."""
    return (not getattr(model, "_int8", False) and getattr(model, "diffusion_dtype", None) == torch.float32
            and all(p.dtype == torch.float32 and p.device.type == "cpu" for p in model.parameters()))


def _python_executable() -> str | None:
    """The Python to start the helper with: this one (Blender's own Python inside Blender), if it is one."""
    exe = sys.executable or ""
    return exe if exe and Path(exe).name.lower().startswith("python") else None


class JobWorker:
    """The caller's side of one helper process: starts it, sends it models and jobs from any thread-unsafe
    caller (one at a time), and hands back results. Writes and reads go through background threads, so a
    call never waits for the helper except `result`."""

    def __init__(self) -> None:
        self.ready = threading.Event()
        self.gone = threading.Event()
        self._results: dict[int, tuple[bytes, float]] = {}   # job id -> (its pickled reply, when it came: monotonic)
        self._dropped: set[int] = set()          # discarded before their reply came: it is dropped then
        self._done = threading.Condition()
        self._outbox: queue.Queue = queue.Queue()
        self._ids = itertools.count()
        self._tokens: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        # id(model) -> (its parameters and buffers, the weights stamp it was sent with); the tensors are kept
        # because walking the module tree for them takes about 1 ms a job
        self._models: dict[int, tuple[list, int]] = {}
        self.problem: str | None = None
        exe = _python_executable()
        if exe is None:
            self._fail(f"no Python executable to start it with ({sys.executable!r})")
            return
        env = dict(os.environ, REMOGEN_WORKER_PATH=os.pathsep.join(p for p in sys.path if p))
        try:
            # its own session (POSIX) or process group (Windows): a Ctrl-C in the caller's terminal is the caller's
            detach = ({"creationflags": subprocess.CREATE_NEW_PROCESS_GROUP} if sys.platform == "win32"
                      else {"start_new_session": True})
            self._proc = subprocess.Popen([exe, "-c", _BOOT, _PACKAGE_DIR, _PACKAGE], stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE, env=env, bufsize=0, **detach)
        except OSError as exc:
            self._fail(f"it could not start ({exc})")
            return
        threading.Thread(target=self._write_loop, daemon=True).start()
        threading.Thread(target=self._read_loop, daemon=True).start()

    # -------------------------------------------------------------- threads
    def _write_loop(self) -> None:
        stdin = self._proc.stdin
        while True:
            data = self._outbox.get()
            if data is None:
                break
            try:
                _write(stdin, data)
            except (OSError, ValueError):
                self._fail("it stopped reading")
                break
        try:
            stdin.close()
        except (OSError, ValueError):
            pass

    def _read_loop(self) -> None:
        # As little Python as possible runs here: inside Blender this thread may run while the main thread is in
        # Blender's own code (an undo step, say), and unpickling a reply's tensors there could start a garbage
        # collection that frees Blender's Python objects under it. Replies are filed as bytes and unpickled by
        # whoever takes them (`result`).
        stdout = self._proc.stdout
        while True:
            try:
                data = _read(stdout)
            except (OSError, ValueError):
                data = None
            if data is None:
                self._fail("it exited")
                return
            job_id = _REPLY_ID.unpack_from(data)[0]
            if job_id == READY_ID:
                self.ready.set()
                continue
            with self._done:
                if job_id in self._dropped:      # nobody wants it any more
                    self._dropped.discard(job_id)
                else:
                    self._results[job_id] = (data, time.monotonic())
                self._done.notify_all()

    def _fail(self, why: str) -> None:
        if not self.gone.is_set():
            self.problem = why
            self.gone.set()
            with self._done:
                self._done.notify_all()

    # -------------------------------------------------------------- sending
    def _send(self, msg: tuple, root: Any = None) -> None:
        buf = io.BytesIO()
        _SpecPickler(buf, self, root).dump(msg)
        self._outbox.put(buf.getvalue())

    def _token(self, obj: Any) -> int:
        token = self._tokens.get(obj)
        if token is None:
            token = next(self._ids)
            self._send(("object", token, obj), root=obj)
            self._tokens[obj] = token
            weakref.finalize(obj, self._forget, ("forget", token))
        return token

    def _forget(self, msg: tuple) -> None:
        if not self.gone.is_set():
            self._outbox.put(pickle.dumps(msg))

    def _send_model(self, model: Any) -> int:
        key = id(model)
        sent = self._models.get(key)
        tensors = sent[0] if sent is not None else list(itertools.chain(model.parameters(), model.buffers()))
        stamp = sum(t._version for t in tensors)
        if sent is None or sent[1] != stamp:
            from .checkpoint import model_payload
            buf = io.BytesIO()
            torch.save(model_payload(model), buf)
            self._outbox.put(pickle.dumps(("model", key, buf.getvalue())))
            if key not in self._models:
                weakref.finalize(model, self._drop_model, key)
            self._models[key] = (tensors, stamp)
        return key

    def _drop_model(self, key: int) -> None:
        self._models.pop(key, None)
        self._forget(("forget_model", key))

    # -------------------------------------------------------------- the API
    @property
    def usable(self) -> bool:
        """Started and not gone: jobs sent now run there."""
        return self.ready.is_set() and not self.gone.is_set()

    def submit(self, model: Any, spec: JobSpec) -> int:
        """Send a job; returns its id for `result`."""
        if not self.usable:
            raise WorkerError(self.problem or "the helper process is still starting")
        key = self._send_model(model)
        job_id = next(self._ids)
        self._send(("job", job_id, key, spec))
        return job_id

    def has_result(self, job_id: int) -> bool:
        """Whether a submitted job's result (or error) has come back."""
        with self._done:
            return job_id in self._results

    def waiting_since(self, job_id: int) -> float:
        """How long (s) a job's result has been back, 0.0 while it is not."""
        with self._done:
            reply = self._results.get(job_id)
        return 0.0 if reply is None else time.monotonic() - reply[1]

    def result(self, job_id: int) -> torch.Tensor:
        """A submitted job's latent, waiting for it if needed. Raises WorkerError when it cannot come."""
        with self._done:
            while job_id not in self._results and not self.gone.is_set():
                self._done.wait()
            reply = self._results.pop(job_id, None)
        msg = None if reply is None else pickle.loads(memoryview(reply[0])[_REPLY_ID.size:])   # our own child's
        if msg is None:
            raise WorkerError(self.problem or "the helper process is gone")
        if msg[0] == "error":
            raise WorkerError(msg[2])
        return msg[2]

    def discard(self, job_id: int) -> None:
        """Forget a job whose result was not taken and is no longer wanted (it may still arrive: then it is
        dropped)."""
        with self._done:
            if self._results.pop(job_id, None) is None:
                self._dropped.add(job_id)

    def close(self, timeout: float = 2.0) -> None:
        """Stop the helper (it also stops by itself when this process ends and its pipe closes)."""
        proc = getattr(self, "_proc", None)
        self._fail("it was closed")
        if proc is None:
            return
        self._outbox.put(pickle.dumps(("quit",)))
        self._outbox.put(None)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()


class RemoteJob:
    """A job running in the helper process, standing in for a DiffusionJob in a ReactionGroup: `advance` has
    nothing to do here, `result` takes the helper's latent (or, when the helper fails, runs the job here)."""

    def __init__(self, worker: JobWorker, model: Any, spec: JobSpec) -> None:
        self.worker, self.model, self.spec = worker, model, spec
        cc = spec.control if spec.targets is not None else None
        self.alpha = spec.alpha
        self.steered_steps = cc.steered_steps if cc else 0
        self.final_steers = cc.final_steers if cc else 0
        self.total_steps = model.cfg.diffusion_steps + self.final_steers
        self._result: torch.Tensor | None = None
        self.slack = 0.0              # how long (s) its latent had been back when it was first asked for
        self.job_id = worker.submit(model, spec)
        self._discard = weakref.finalize(self, worker.discard, self.job_id)   # unless its result is taken

    def advance(self, steps: int) -> None:
        """Nothing to do in this process: the helper runs the whole job."""

    @property
    def result(self) -> torch.Tensor:
        if self._result is None:
            self.slack = self.worker.waiting_since(self.job_id)
            try:
                self._result = self.worker.result(self.job_id)
            except WorkerError as exc:
                _warn_once(str(exc))
                self._result = run_job(self.model, self.spec)
            finally:
                self._discard.detach()      # its reply, if any, is taken: nothing to discard later
        return self._result

    def snapshot(self) -> None:
        return None           # a pure function of its spec: nothing a failed frame could have changed

    def restore(self, snap: None) -> None:
        pass


_warned: set[str] = set()


def _warn_once(why: str) -> None:
    if why not in _warned:
        _warned.add(why)
        warnings.warn(f"the diffusion helper process failed ({why}); running the diffusion in this process "
                      "(slower, the same motion)", RuntimeWarning, stacklevel=3)


_shared: JobWorker | None = None
_shared_lock = threading.Lock()


def shared_worker() -> JobWorker:
    """The process-wide helper, started on first use (its start takes a second or two: until it is ready,
    jobs run in this process). One that failed is not restarted: jobs then run in this process."""
    global _shared
    with _shared_lock:
        if _shared is None:
            _shared = JobWorker()
        return _shared


def close_shared_worker() -> None:
    global _shared
    with _shared_lock:
        if _shared is not None:
            _shared.close()
            _shared = None


atexit.register(close_shared_worker)
