"""Timelines: what a projection's monitor logged, translated into fluents, events and
quantities (:func:`translate_records`)."""

from __future__ import annotations

from projection_server.timeline.translate import translate_records

__all__ = ['translate_records']
