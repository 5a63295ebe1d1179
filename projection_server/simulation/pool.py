"""Supervised worker processes that run projections, and the cache of finished bags.

Modelled on Gymnasium's ``AsyncVectorEnv``: each worker is a process of an explicit
multiprocessing context (``forkserver`` by default: the parent hosts rclpy and Prolog and
must never be forked) with its own DIRECT-mode PyBullet client, and answers every command
with ``(result, ok)``; exceptions travel back as :class:`ProjectionError`. Every wait in the
parent has a time limit. A worker that crashes or runs over its projection's time limit is
terminated, its projection fails with kind ``worker_crashed`` or ``timeout``, and a new
worker is started for the next projection. Each projection builds a fresh world.

Bags are named after the projection's content key (:meth:`Job.key`), written under a
temporary name and renamed into place when complete, so an identical projection is answered
from the bag directory, also across processes and restarts, and a bag is never overwritten.
After each new bag the :class:`Retention` policy deletes the least recently used bags.
"""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass
import itertools
import multiprocessing
from multiprocessing.connection import wait
import os
from pathlib import Path
import queue
import shutil
import threading
import traceback
from typing import Any, NoReturn, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError
from projection_server.simulation.settings import load_settings, Settings

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.job import Job

__all__ = ['Retention', 'WorkerPool']

TMP_PREFIX = '.tmp-'
_POLL = 1.0   # s between liveness checks while waiting for a result


@dataclass(frozen=True)
class Retention:
    """Keep at most ``max_bags`` bags and ``max_bytes`` bytes (None: no limit)."""

    max_bags: int | None = 1000
    max_bytes: int | None = 4 * 1024 ** 3

    @classmethod
    def of(cls, value: Retention | Mapping[str, Any] | None) -> Retention:
        """From a Retention, a mapping with the same keys (e.g. from Prolog) or None."""
        if value is None:
            return cls()
        if isinstance(value, Retention):
            return value
        try:
            return cls(**dict(value))
        except TypeError as exc:
            raise ProjectionError('invalid_settings', f'retention: {exc}') from exc

    def apply(self, bag_dir: Path, keep: Path) -> None:
        """Delete the least recently used bags of ``bag_dir`` beyond the limits; not ``keep``."""
        bags = []
        for entry in bag_dir.iterdir():
            if entry.name.startswith('.') or not (entry / 'metadata.yaml').is_file():
                continue
            try:
                size = sum(f.stat().st_size for f in entry.iterdir())
                bags.append((entry.stat().st_mtime_ns, entry.name, size, entry))
            except FileNotFoundError:   # deleted by another process meanwhile
                continue
        bags.sort()
        count, total = len(bags), sum(b[2] for b in bags)
        for _, _, size, path in bags:
            if not ((self.max_bags is not None and count > self.max_bags)
                    or (self.max_bytes is not None and total > self.max_bytes)):
                break
            if path == keep:
                continue
            shutil.rmtree(path, ignore_errors=True)
            count, total = count - 1, total - size


@dataclass
class _Request:
    job: Job
    key: str
    timeout: float
    future: Future[str]


class WorkerPool:
    """``workers`` supervised projection processes writing bags into ``bag_dir``.

    ``submit`` queues a projection and returns a :class:`~concurrent.futures.Future` of its
    bag path; identical projections (same key) share one future and one bag. ``run`` is
    submit and wait. Close the pool (or use it as a context manager) to stop the workers.
    """

    def __init__(self, bag_dir: str | os.PathLike[str], workers: int = 1,
                 settings: Settings | None = None,
                 retention: Retention | Mapping[str, Any] | None = None,
                 start_method: str = 'forkserver', startup_timeout: float = 60.0):
        if not isinstance(workers, int) or workers < 1:
            raise ProjectionError('invalid_settings', f'workers must be >= 1, got {workers!r}')
        self.bag_dir = Path(bag_dir).expanduser()
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.settings = settings if settings is not None else load_settings()
        self.retention = Retention.of(retention)
        self.startup_timeout = startup_timeout
        self._context = multiprocessing.get_context(start_method)
        self._queue: queue.Queue[_Request | None] = queue.Queue()
        self._futures: dict[str, Future[str]] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._counter = itertools.count()
        self._remove_stale_tmp()
        self._slots = [_Slot(self, i) for i in range(workers)]

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def worker_pids(self) -> list[int | None]:
        """Process ids of the running workers (None where none is running)."""
        return [slot.pid for slot in self._slots]

    def submit(self, job: Job, timeout: float) -> Future[str]:
        """Queue ``job``; its simulation may take ``timeout`` seconds of wall-clock time.

        The time limit counts from when a worker takes the job, not from submission.
        """
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or timeout <= 0:
            raise ProjectionError('invalid_parameters', f'timeout must be > 0 s: {timeout!r}')
        key = job.key(self.settings)
        with self._lock:
            if self._closed:
                raise ProjectionError('pool_closed', 'the projection pool is closed')
            future = self._futures.get(key)
            if future is not None and (not future.done() or _usable(future)):
                if future.done():
                    _touch(Path(future.result()))
                return future
            future = Future()
            self._futures[key] = future
            final = self.bag_dir / self._bag_name(job, key)
            if final.is_dir():
                _touch(final)
                future.set_result(str(final))
                return future
            self._queue.put(_Request(job, key, float(timeout), future))
        return future

    def run(self, job: Job, timeout: float) -> str:
        """Run ``job`` (or find its bag) and return the bag's path.

        Raises:
            ProjectionError: of the projection, or kind ``pool_closed``.
        """
        future = self.submit(job, timeout)
        while True:
            try:
                return future.result(timeout=_POLL)
            except TimeoutError:
                if not any(slot.alive for slot in self._slots):
                    raise ProjectionError('pool_closed', 'no worker supervisor is running')

    def close(self) -> None:
        """Stop the workers; queued projections fail with kind ``pool_closed``."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        while True:
            try:
                request = self._queue.get_nowait()
            except queue.Empty:
                break
            if request is not None and request.future.set_running_or_notify_cancel():
                request.future.set_exception(
                    ProjectionError('pool_closed', 'the projection pool was closed'))
        for _ in self._slots:
            self._queue.put(None)
        for slot in self._slots:
            slot.terminate_worker()   # a running projection fails with kind pool_closed
        for slot in self._slots:
            slot.join(10.0)

    # --- used by the slots --------------------------------------------------------------
    def _tmp_dir(self) -> Path:
        """A new private directory for writing a bag under its final name."""
        tmp = self.bag_dir / f'{TMP_PREFIX}{os.getpid()}-{next(self._counter)}'
        tmp.mkdir()
        return tmp

    def _publish(self, bag: Path) -> Path:
        """Move a complete bag into place; an existing bag of the same key wins."""
        final = self.bag_dir / bag.name
        try:
            bag.rename(final)
        except OSError:
            if not final.is_dir():
                raise   # otherwise made meanwhile by another process: keep that one
        self.retention.apply(self.bag_dir, keep=final)
        return final

    def _failed(self, request: _Request, error: ProjectionError) -> None:
        with self._lock:
            if self._futures.get(request.key) is request.future:
                del self._futures[request.key]
        request.future.set_exception(error)

    @staticmethod
    def _bag_name(job: Job, key: str) -> str:
        return f'{job.program}-{key[:24]}'

    def _remove_stale_tmp(self) -> None:
        """Delete temporary bags left by dead processes (crashes, kills)."""
        for entry in self.bag_dir.glob(TMP_PREFIX + '*'):
            try:
                pid = int(entry.name[len(TMP_PREFIX):].split('-')[0])
                os.kill(pid, 0)
            except ValueError:
                continue
            except ProcessLookupError:
                shutil.rmtree(entry, ignore_errors=True)
            except PermissionError:   # alive, someone else's
                continue


class _Slot:
    """One worker process and the thread that feeds and supervises it."""

    def __init__(self, pool: WorkerPool, index: int):
        self._pool = pool
        self._process: Any = None
        self._conn: Any = None
        self._thread = threading.Thread(target=self._loop, name=f'projection-worker-{index}',
                                        daemon=True)
        self._thread.start()

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    @property
    def pid(self) -> int | None:
        process = self._process
        return process.pid if process is not None and process.is_alive() else None

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)

    def terminate_worker(self) -> None:
        """Ask the running worker to stop (SIGTERM); its supervisor thread cleans up."""
        process = self._process
        if process is not None:
            try:
                process.terminate()
            except (ValueError, AttributeError):   # closed by the supervisor meanwhile
                pass

    def _loop(self) -> None:
        try:
            while (request := self._pool._queue.get()) is not None:
                if not request.future.set_running_or_notify_cancel():
                    continue
                try:
                    path = self._execute(request)
                except ProjectionError as exc:
                    self._pool._failed(request, exc)
                except Exception as exc:  # a bug here must fail the projection, not hang it
                    self._pool._failed(request, ProjectionError(
                        'simulation_failed', f'{type(exc).__name__}: {exc}'))
                else:
                    request.future.set_result(str(path))
        finally:
            self._stop()

    def _execute(self, request: _Request) -> Path:
        self._ensure_worker()
        tmp = self._pool._tmp_dir()
        # The bag is written under its final name, which is also the name of its storage
        # file inside: identical projections give byte-identical bags.
        bag = tmp / self._pool._bag_name(request.job, request.key)
        what = f'projection {request.key[:12]}'
        try:
            try:
                self._conn.send(('project', (request.job, str(bag))))
            except OSError:   # the worker died while idle
                self._died(what)
            result, ok = self._receive(request.timeout, what)
            if not ok:
                raise result
            return self._pool._publish(bag)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)

    def _receive(self, timeout: float, what: str) -> tuple[Any, bool]:
        """The worker's answer within ``timeout`` s; on failure the worker is killed."""
        ready = wait([self._conn, self._process.sentinel], timeout=timeout)
        if not ready:
            self._kill()
            raise ProjectionError('timeout', f'{what} took longer than {timeout:g} s')
        try:
            # A dying worker's pipe reads as EOF, so the pipe is checked first.
            if self._conn.poll():
                return self._conn.recv()
        except (EOFError, OSError):
            pass
        self._died(what)

    def _died(self, what: str) -> NoReturn:
        self._process.join(1.0)
        code = self._process.exitcode
        self._kill()
        if self._pool._closed:
            raise ProjectionError('pool_closed', f'the pool was closed during {what}')
        raise ProjectionError('worker_crashed', f'worker died during {what} (exit code {code})')

    def _ensure_worker(self) -> None:
        if self._process is not None and self._process.is_alive():
            return
        self._kill()
        context = self._pool._context
        parent, child = context.Pipe()
        process = context.Process(target=_worker_main,
                                  args=(child, self._pool.settings.to_dict()),
                                  name='projection-worker', daemon=True)
        process.start()
        child.close()
        self._process, self._conn = process, parent
        message, ok = self._receive(self._pool.startup_timeout, 'worker start-up')
        if not ok:
            self._kill()
            raise message

    def _kill(self) -> None:
        process, conn = self._process, self._conn
        self._process = self._conn = None
        if conn is not None:
            conn.close()
        if process is not None:
            if process.is_alive():
                process.terminate()
                process.join(2.0)
            if process.is_alive():
                process.kill()
                process.join(2.0)
            if not process.is_alive():
                process.close()

    def _stop(self) -> None:
        if self._conn is not None and self._process is not None and self._process.is_alive():
            try:
                self._conn.send(('close', None))
                self._process.join(5.0)
            except OSError:
                pass
        self._kill()


def _usable(future: Future[str]) -> bool:
    """A finished future whose bag still exists (retention may have deleted it)."""
    return (not future.cancelled() and future.exception() is None
            and Path(future.result()).is_dir())


def _touch(path: Path) -> None:
    try:
        os.utime(path)
    except FileNotFoundError:
        pass


def _worker_main(conn: Any, settings: dict[str, Any]) -> None:
    """Entry point of a worker process: answers commands with ``(result, ok)``."""
    import signal

    # Ctrl-C belongs to the parent, which stops its workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # PyBullet's C code prints banners on stdout (the parent's, e.g. a ROS node's); errors
    # travel back through the pipe and stderr stays open.
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    try:
        from projection_server.simulation.runner import run_projection

        parsed = Settings.from_dict(settings)
    except Exception as exc:
        conn.send((ProjectionError('simulation_failed', f'worker start-up: {exc}'), False))
        return
    conn.send(('ready', True))
    while True:
        try:
            command, payload = conn.recv()
        except (EOFError, OSError):
            return
        if command == 'close':
            return
        try:
            job, path = payload
            run_projection(job, parsed, Path(path))
            conn.send((path, True))
        except ProjectionError as exc:
            conn.send((exc, False))
        except Exception as exc:
            conn.send((ProjectionError(
                'simulation_failed',
                f'{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}'), False))
