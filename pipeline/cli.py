"""The ``stridelab`` command line (DESIGN.md "Command line")."""
from __future__ import annotations

import importlib
import pkgutil

import click

from pipeline import bench as bench_pkg


class _BenchGroup(click.Group):
    """``stridelab bench``: subcommands discovered from ``pipeline.bench.<module>.command``."""

    def _commands(self) -> dict[str, click.Command]:
        found = {}
        for mod in pkgutil.iter_modules(bench_pkg.__path__):
            if mod.name.startswith("_"):
                continue
            m = importlib.import_module(f"pipeline.bench.{mod.name}")
            cmd = getattr(m, "command", None)
            if isinstance(cmd, click.Command):
                found[cmd.name] = cmd
        return found

    def list_commands(self, ctx):
        return sorted(self._commands())

    def get_command(self, ctx, name):
        return self._commands().get(name)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="stridelab")
def main() -> None:
    """StrideLab: wearable-IMU gait and activity pipeline.

    \b
    Examples:
      stridelab demo --no-serve          # simulate a study, run the nightly pipeline
      stridelab simulate inbox/          # write a synthetic study as MCAP files
      stridelab ingest inbox/*.mcap      # load recordings into the warehouse
      stridelab run --jobs 2             # nightly: ingest new files, recompute what is stale
      stridelab bench ingest --json      # ingest speed
    """


@main.group(cls=_BenchGroup)
def bench() -> None:
    """Accuracy and speed benchmarks against public data and reference libraries."""
