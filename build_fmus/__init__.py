"""Builds the plant FMUs of dfwb with pythonfmu and makes them FMI-compliant."""

from .builder import build_all, source_hash

__all__ = ["build_all", "source_hash"]
