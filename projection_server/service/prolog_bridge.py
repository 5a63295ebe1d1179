"""The one module that calls SWI-Prolog (through janus).

Every Prolog call of the server goes through here. Values are always passed
through janus' ``inputs`` dict, never formatted into goal text.

Threading: janus gives each Python thread that calls Prolog its own Prolog
engine, and releases the GIL while Prolog runs. A query opened with
:func:`solutions` lives on the engine of the thread that opened it and must be
advanced and closed from that thread.
"""

from __future__ import annotations

from contextlib import contextmanager
import os
import threading
from typing import Any, Iterator, TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Mapping

__all__ = [
    'BridgeError',
    'attach_engine',
    'check',
    'detach_engine',
    'interrupt',
    'is_abort',
    'load',
    'prolog_dir',
    'solutions',
]

_janus = None
_load_lock = threading.Lock()


class BridgeError(Exception):
    """Prolog could not be loaded or called."""


def _j():
    global _janus
    if _janus is None:
        try:
            import janus_swi
        except ImportError as exc:
            raise BridgeError(f'janus_swi is not importable: {exc}') from exc
        _janus = janus_swi
    return _janus


def prolog_dir() -> str:
    """Directory of the installed Prolog sources (share/projection_server/prolog)."""
    from ament_index_python.packages import get_package_share_directory
    return os.path.join(get_package_share_directory('projection_server'), 'prolog')


def load(directory: str | None = None, options: Mapping[str, Any] | None = None) -> None:
    """Load the server's Prolog sources and initialise them with ``options``."""
    directory = directory or prolog_dir()
    main = os.path.join(directory, 'projection_server.pl')
    if not os.path.isfile(main):
        raise BridgeError(f'Prolog sources not found: {main}')
    janus = _j()
    with _load_lock:
        try:
            janus.query_once('use_module(File)', {'File': main})
            janus.query_once('projection_server:projection_server_init(Options)',
                             {'Options': dict(options or {})})
        except janus.PrologError as exc:
            raise BridgeError(f'loading {main} failed: {exc}') from exc


def attach_engine() -> int:
    """Attach a Prolog engine to the calling thread; return its Prolog thread id."""
    return _j().attach_engine()


def detach_engine() -> None:
    """Release the engine attached by :func:`attach_engine` on this thread."""
    _j().detach_engine()


def check(text: str, options: Mapping[str, Any]) -> dict:
    """Parse and safety-check query text without running it."""
    return _call('query_service:query_check(Text, Options, Result)', text, options)


@contextmanager
def solutions(text: str, options: Mapping[str, Any]) -> Iterator[Iterator[dict]]:
    """Open the query; yield an iterator of result dicts. Closes the query on exit.

    Each result is ``{'status': 'solution', 'bindings': json}`` or, as the last
    one, ``{'status': 'error', 'kind': ..., 'message': ..., 'error': json}``.
    """
    janus = _j()
    q = janus.query('query_service:query_solution(Text, Options, Result)',
                    {'Text': text, 'Options': dict(options)})
    try:
        yield (d['Result'] for d in q)
    finally:
        q.close()


def interrupt(thread_id: int) -> bool:
    """Abort whatever the Prolog engine ``thread_id`` is running.

    Used for queries that outlived their time limit, e.g. because they catch
    it: unlike other exceptions, an abort cannot be caught by a query's
    catch-all. Returns False when that engine no longer exists.
    """
    try:
        return bool(_j().query_once('catch(thread_signal(Id, abort), _, fail)',
                                    {'Id': thread_id})['truth'])
    except _j().PrologError:
        return False


def is_abort(exc: BaseException) -> bool:
    """Whether ``exc`` (raised by a janus call) is Prolog's abort, not an error of the goal."""
    janus = _j()
    if not isinstance(exc, janus.PrologError) or exc.term is None:
        return False
    try:
        return repr(exc) in ("'$aborted'", 'unwind(abort)')
    except Exception:  # noqa: BLE001 - the engine may be going away
        return False


def _call(goal: str, text: str, options: Mapping[str, Any]) -> dict:
    janus = _j()
    try:
        return janus.query_once(goal, {'Text': text, 'Options': dict(options)})['Result']
    except janus.PrologError as exc:
        return {'status': 'error', 'kind': 'system_error', 'message': str(exc), 'error': ''}
