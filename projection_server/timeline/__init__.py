"""Timelines: bags of projections translated into fluents, events and quantities."""

from __future__ import annotations

from projection_server.timeline.translate import translate_bag

__all__ = ['translate_bag']
