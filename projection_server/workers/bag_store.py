"""The bag directory: where finished projections are kept, whichever backend made them.

Bags are named after the projection's content key (:meth:`Job.key`), written under a
temporary name and renamed into place when complete, so an identical projection is answered
from the bag directory, also across processes and restarts, and a bag is never overwritten.
After each new bag the :class:`Retention` policy deletes the least recently used bags.
"""

from __future__ import annotations

from dataclasses import dataclass
import itertools
import os
from pathlib import Path
import shutil
from typing import Any, TYPE_CHECKING

from projection_server.simulation.errors import ProjectionError

if TYPE_CHECKING:
    from collections.abc import Mapping

    from projection_server.simulation.job import Job

__all__ = ['BagStore', 'Retention', 'TMP_PREFIX']

TMP_PREFIX = '.tmp-'


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


class BagStore:
    """The bags of one bag directory, by job key, with their retention policy."""

    def __init__(self, bag_dir: str | os.PathLike[str],
                 retention: Retention | Mapping[str, Any] | None = None):
        self.bag_dir = Path(bag_dir).expanduser()
        self.bag_dir.mkdir(parents=True, exist_ok=True)
        self.retention = Retention.of(retention)
        self._counter = itertools.count()
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
        touch(final)
        return final

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
        self.retention.apply(self.bag_dir, keep=final)
        return final

    def remove_stale_tmp(self) -> None:
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


def touch(path: Path) -> None:
    """Mark a bag as just used (retention deletes the least recently used)."""
    try:
        os.utime(path)
    except FileNotFoundError:
        pass
