"""The bag directory: where finished projections are kept, whichever backend made them.

Bags are named after the projection's content key (:meth:`Job.key`), written under a
temporary name and renamed into place when complete, so an identical projection is answered
from the bag directory, also across processes and restarts, and a bag is never overwritten.
After each new bag the :class:`Retention` policy deletes the least recently used bags.

A store keeps an index of its directory's bags (name, size, least recently used first), so
that a new bag costs its retention check in memory rather than a scan of the whole
directory (30-50 ms with 1,000 bags, the default limit, per projection). The index is
rebuilt from the directory every :data:`RESCAN_EVERY` new bags, which takes in what other
processes sharing the directory did meanwhile.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
import itertools
import os
from pathlib import Path
import shutil
import tempfile
import threading
from typing import Any, TYPE_CHECKING

from projection_server.errors import ErrorKind, ProjectionError

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.job import Job

__all__ = ['RESCAN_EVERY', 'BagStore', 'Retention', 'TMP_PREFIX', 'private_tmp_dir',
           'remove_orphans']

TMP_PREFIX = '.tmp-'
RESCAN_EVERY = 100   # new bags between two scans of the directory into a store's index


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
            raise ProjectionError(ErrorKind.INVALID_SETTINGS, f'retention: {exc}') from exc

    def exceeded(self, count: int, total: int) -> bool:
        """Whether ``count`` bags of ``total`` bytes are more than this policy keeps."""
        return ((self.max_bags is not None and count > self.max_bags)
                or (self.max_bytes is not None and total > self.max_bytes))

    def apply(self, bag_dir: Path, keep: Path) -> None:
        """Delete the least recently used bags of ``bag_dir`` beyond the limits; not ``keep``."""
        bags = scan(bag_dir)
        count, total = len(bags), sum(bags.values())
        for name, size in bags.items():
            if not self.exceeded(count, total):
                break
            if bag_dir / name == keep:
                continue
            shutil.rmtree(bag_dir / name, ignore_errors=True)
            count, total = count - 1, total - size


def scan(bag_dir: Path) -> OrderedDict[str, int]:
    """The finished bags of ``bag_dir``: name -> bytes, least recently used first."""
    bags = []
    for entry in bag_dir.iterdir():
        if entry.name.startswith('.') or not (entry / 'metadata.yaml').is_file():
            continue
        try:
            bags.append((entry.stat().st_mtime_ns, entry.name, _size(entry)))
        except FileNotFoundError:   # deleted by another process meanwhile
            continue
    bags.sort()
    return OrderedDict((name, size) for _, name, size in bags)


def _size(bag: Path) -> int:
    return sum(f.stat().st_size for f in bag.iterdir())


class BagStore:
    """The bags of one bag directory, by job key, with their retention policy."""

    def __init__(self, bag_dir: str | os.PathLike[str],
                 retention: Retention | Mapping[str, Any] | None = None):
        self.bag_dir = Path(bag_dir).expanduser()
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.retention = Retention.of(retention)
        self._counter = itertools.count()
        self._lock = threading.Lock()   # publish runs on each worker's thread
        self._index: OrderedDict[str, int] | None = None   # scanned when first needed
        self._bytes = 0
        self._since_scan = 0
        self.remove_stale_tmp()

    @staticmethod
    def name(job: Job, key: str) -> str:
        """The bag's name (and that of its storage file inside): program and key."""
        return f'{job.program}-{key[:24]}'

    def path(self, job: Job, key: str) -> Path:
        return self.bag_dir / self.name(job, key)

    def existing(self, job: Job, key: str) -> Path | None:
        """The finished bag of this projection, marked as just used; None if there is none."""
        final = self.path(job, key)
        if not final.is_dir():
            return None
        self.touch(final)
        return final

    def touch(self, bag: Path) -> None:
        """Mark a bag of this store as just used."""
        touch(bag)
        with self._lock:
            if self._index is not None and bag.name in self._index:
                self._index.move_to_end(bag.name)

    def tmp_dir(self) -> Path:
        """A new private directory for writing a bag under its final name."""
        tmp = self.bag_dir / f'{TMP_PREFIX}{os.getpid()}-{next(self._counter)}'
        tmp.mkdir()
        return tmp

    def publish(self, bag: Path) -> Path:
        """Move a complete bag into place; an existing bag of the same key wins."""
        final = self.bag_dir / bag.name
        try:
            bag.rename(final)
        except OSError:
            if not final.is_dir():
                raise   # otherwise made meanwhile by another process: keep that one
        try:
            size = _size(final)
        except FileNotFoundError:   # deleted by another process's retention meanwhile
            return final
        with self._lock:
            self._since_scan += 1
            if self._index is None or self._since_scan >= RESCAN_EVERY:
                self._rescan()
            elif final.name not in self._index:
                self._index[final.name] = size
                self._bytes += size
            self._index.move_to_end(final.name)
            self._evict(keep=final.name)
        return final

    def _rescan(self) -> None:
        self._index = scan(self.bag_dir)
        self._bytes = sum(self._index.values())
        self._since_scan = 0

    def _evict(self, keep: str) -> None:
        """Delete least recently used bags until the index is within the limits."""
        assert self._index is not None
        while self.retention.exceeded(len(self._index), self._bytes):
            name, size = next(iter(self._index.items()))
            if name == keep:
                break
            del self._index[name]
            self._bytes -= size
            shutil.rmtree(self.bag_dir / name, ignore_errors=True)

    def remove_stale_tmp(self) -> None:
        """Delete temporary bags left by dead processes (crashes, kills)."""
        remove_orphans(self.bag_dir, TMP_PREFIX)


def remove_orphans(parent: Path, prefix: str) -> None:
    """Delete the directories ``parent/<prefix><pid>-...`` whose process is gone."""
    for entry in parent.glob(prefix + '*'):
        try:
            pid = int(entry.name[len(prefix):].split('-')[0])
            os.kill(pid, 0)
        except ValueError:
            continue
        except ProcessLookupError:
            shutil.rmtree(entry, ignore_errors=True)
        except PermissionError:   # alive, someone else's
            continue


def private_tmp_dir(prefix: str) -> Path:
    """A new directory ``<tmp>/<prefix><pid>-...`` of this process, after deleting those of
    processes that are gone (a worker killed while it wrote there leaves its directory)."""
    parent = Path(tempfile.gettempdir())
    remove_orphans(parent, prefix)
    return Path(tempfile.mkdtemp(prefix=f'{prefix}{os.getpid()}-', dir=parent))


def touch(path: Path) -> None:
    """Mark a bag as just used (retention deletes the least recently used)."""
    try:
        os.utime(path)
    except FileNotFoundError:
        pass
