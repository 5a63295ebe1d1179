"""What the node knows of the robot's world: its description, its joints, its transforms.

One :class:`RobotWorld` is fed by the node's subscriptions (:mod:`.listener`) and read by
snapshots (:mod:`.snapshot`), from any thread. Joint states are merged by joint name,
since several publishers may each send some joints (an arm's driver, a gripper's).
"""

from __future__ import annotations

from dataclasses import dataclass
import threading
import time
from typing import Callable, Iterable

from projection_server.world.transforms import Transform, TransformBuffer

__all__ = ['Description', 'JointState', 'RobotWorld']


@dataclass(frozen=True)
class Description:
    """The URDF text last received, and when (ns of the node's clock)."""

    text: str
    received: int


@dataclass(frozen=True)
class JointState:
    """One joint's last position and its stamp (ns)."""

    position: float
    stamp: int


class RobotWorld:
    """The robot's description, joint states and transforms as last received."""

    def __init__(self, clock: Callable[[], int] | None = None, topics: dict | None = None):
        self._clock = clock or time.time_ns
        self.topics = dict(topics or {})   # role -> resolved topic name, for messages
        self.transforms = TransformBuffer()
        self._description: Description | None = None
        self._joints: dict[str, JointState] = {}
        self._changed = threading.Condition()

    def now(self) -> int:
        """The node's time (ns): what ages are measured against."""
        return self._clock()

    def set_description(self, text: str) -> None:
        with self._changed:
            self._description = Description(text, self.now())
            self._changed.notify_all()

    def description(self) -> Description | None:
        with self._changed:
            return self._description

    def update_joints(self, names: Iterable[str], positions: Iterable[float],
                      stamp: int) -> None:
        """Merge one ``JointState`` message: the joints it names, the others kept."""
        with self._changed:
            for name, position in zip(names, positions):
                self._joints[name] = JointState(float(position), stamp)
            self._changed.notify_all()

    def joints(self) -> dict[str, JointState]:
        with self._changed:
            return dict(self._joints)

    def add_transforms(self, transforms: Iterable[Transform]) -> None:
        for t in transforms:
            self.transforms.add(t)
        with self._changed:
            self._changed.notify_all()

    def wait(self, seconds: float) -> None:
        """Wait at most ``seconds`` for anything new to arrive."""
        with self._changed:
            self._changed.wait(max(0.0, seconds))
