"""Logging set-up shared by the workflow's script adapters and the CLI."""

from __future__ import annotations

import logging
import sys
from pathlib import Path


def to_file(path: str | Path, level: int = logging.INFO) -> logging.Logger:
    """Send railtherm's log records (and warnings) to ``path``; return the package logger."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logger = logging.getLogger("railtherm")
    logger.handlers[:] = [handler]
    logger.setLevel(level)
    logging.captureWarnings(True)
    logging.getLogger("py.warnings").handlers[:] = [handler]

    def log_uncaught(kind, error, trace):
        logger.error("stopped: %s", error, exc_info=(kind, error, trace))
        sys.__excepthook__(kind, error, trace)

    sys.excepthook = log_uncaught
    return logger
