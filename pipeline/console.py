"""Console helpers shared by all commands: progress bars, one-line errors, JSON output."""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from typing import Iterator

import click
import numpy as np
from rich.console import Console
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn,
                           TimeElapsedColumn, TimeRemainingColumn)

#: progress and human messages go to stderr so that ``--json`` output on stdout stays machine-readable
err_console = Console(stderr=True, soft_wrap=True)


class UserError(click.ClickException):
    """A problem with the user's input: printed as one line ``error: ...`` and exit code 2."""
    exit_code = 2

    def show(self, file=None) -> None:  # noqa: D102 - one line, no traceback
        click.echo(f"error: {self.format_message()}", err=True)


@contextmanager
def progress(enabled: bool = True) -> Iterator[Progress]:
    """A rich progress bar on stderr (disabled when stderr is not a terminal or ``enabled`` is False)."""
    p = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                 TimeElapsedColumn(), TimeRemainingColumn(), console=err_console,
                 disable=not enabled or not err_console.is_terminal, transient=False)
    with p:
        yield p


def _default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def emit_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (NumPy scalars and arrays converted)."""
    json.dump(obj, sys.stdout, indent=2, default=_default, allow_nan=False)
    sys.stdout.write("\n")
