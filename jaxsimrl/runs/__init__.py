"""Run directories: atomic writes, resolved config, metrics files, checkpoints, progress display."""

from jaxsimrl.runs.atomic import atomic_write_bytes, atomic_write_json, atomic_write_text

__all__ = ["atomic_write_bytes", "atomic_write_json", "atomic_write_text"]
