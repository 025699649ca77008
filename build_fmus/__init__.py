"""Builds the plant FMUs of dfwb with pythonfmu and makes them FMI-compliant."""

from .builder import BuildError, build, build_all, source_hash, sources

__all__ = ["build", "build_all", "source_hash", "sources", "BuildError"]
