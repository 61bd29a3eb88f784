"""Shared fixtures: project paths, the public data folder, small real MCAP recordings."""
from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parent.parent
SHARED_DATA = PROJECT_ROOT.parent / "shared" / "data"
LAYERS = ("estimators", "warehouse", "pipeline", "reports", "dashboard", "validation", "studies")


class _NoBareLayerImports(importlib.abc.MetaPathFinder):
    """The layers are installed as ``stridelab.<layer>`` only; pytest puts the repository root on ``sys.path``, where
    ``import stridelab.pipeline`` would still find the folder and load a second copy of it beside ``stridelab.pipeline``. A
    bare layer name (an import, a ``mock.patch`` target, a pickled reference) fails here as it would installed.
    tests/test_layers.py checks the import statements; this catches the names in strings."""

    def find_spec(self, fullname, path=None, target=None):
        if path is None and fullname in LAYERS:
            spec = importlib.machinery.PathFinder.find_spec(fullname)
            if spec is not None and spec.origin and Path(spec.origin).resolve().is_relative_to(PROJECT_ROOT):
                raise ModuleNotFoundError(f"import stridelab.{fullname}, not {fullname}: the layers are installed "
                                          f"under the stridelab namespace (docs/architecture.md)", name=fullname)
        return None


sys.meta_path.insert(0, _NoBareLayerImports())


def shared_data(name: str) -> Path:
    """Folder of a public data set in ../shared/data, or skip the test with the reason. A test (or its fixture)
    that reads it must be marked ``realdata`` (``make test-fast`` leaves those out): it fails here otherwise."""
    item = _RUNNING[-1] if _RUNNING else None
    if item is not None and item.get_closest_marker("realdata") is None:
        pytest.fail(f"{item.nodeid} reads ../shared/data/{name} but is not marked realdata: add "
                    f"@pytest.mark.realdata (tests/conftest.py)", pytrace=False)
    p = SHARED_DATA / name
    if not p.is_dir():
        pytest.skip(f"public data '{name}' not found at {p}; see DESIGN.md 'Real data' (needs ../shared/data)")
    return p


@pytest.fixture(scope="session")
def small_home(tmp_path_factory) -> Path:
    """A StrideLab home made the real way: the demo study cut to one participant with 6-min chest days,
    simulated to MCAP and run through every stage (``home/warehouse``, ``home/inbox``). For the Python API,
    export and examples tests."""
    from stridelab.pipeline import runner
    from stridelab.validation.simulate import simulate_to_dir
    home = tmp_path_factory.mktemp("home")
    simulate_to_dir(home / "inbox", participants=1, hours=0.1, jobs=2)
    summary = runner.run(home / "warehouse", home / "inbox", jobs=2, command="run")
    assert not summary.failed and not summary.quarantined, summary.as_dict()
    return home


# --- pytest-xdist (``make test`` runs ``-n 2 --dist loadgroup``) ------------------------------------------------
# Every test module is one unit of work (its module-scoped fixtures are built once), and modules that share an
# expensive session fixture of a conftest (``demo_wh``, ``small_home``, the live lab session, ...) are one unit too:
# each such fixture is then built once, on one worker, as in a run without xdist. The units are handed out longest
# first (estimated from the ``slow``/``browser``/``realdata`` markers) so that neither worker is left with a long
# unit at the end. Without xdist (``python -m pytest`` alone) none of this applies.
UNIT_WEIGHT_SLOW = 20          # a slow test counts as this many quick ones when the units are ordered


def _is_xdist_worker(config) -> bool:
    return hasattr(config, "workerinput") and bool(getattr(config.option, "loadgroup", False))


def pytest_configure(config):
    if getattr(config.option, "dist", "no") == "loadgroup" and hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False      # keep the order below (xdist would sort by test count)


def _shared_session_fixtures(item) -> set[str]:
    """Session-scoped fixtures of a tests/**/conftest.py that ``item`` uses."""
    info = getattr(item, "_fixtureinfo", None)
    names = set()
    for name, defs in (info.name2fixturedefs.items() if info else ()):
        d = defs[-1]
        if d.scope == "session" and d.baseid and not d.baseid.endswith(".py"):
            names.add(name)
    return names


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    if not _is_xdist_worker(config):
        return
    parent: dict[str, str] = {}

    def find(x: str) -> str:
        while parent.setdefault(x, x) != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for item in items:
        mod = find(item.nodeid.split("::")[0])
        for fx in _shared_session_fixtures(item):
            parent[find(f"fixture:{fx}")] = mod
    weight: dict[str, int] = {}
    for item in items:
        unit = find(item.nodeid.split("::")[0])
        slow = any(item.get_closest_marker(m) for m in ("slow", "browser", "realdata"))
        weight[unit] = weight.get(unit, 0) + (UNIT_WEIGHT_SLOW if slow else 1)
        item.add_marker(pytest.mark.xdist_group(unit))
    order = {id(it): i for i, it in enumerate(items)}
    items.sort(key=lambda it: (-weight[find(it.nodeid.split("::")[0])], find(it.nodeid.split("::")[0]),
                               order[id(it)]))


@pytest.hookimpl(trylast=True, specname="pytest_collection_modifyitems")
def pytest_collection_modifyitems_xdist_group_suffix(config, items):
    """The ``@<group>`` suffix of each test id, which ``--dist loadgroup`` schedules by. pytest-xdist 3.8 adds it by
    assigning ``item._nodeid``, which pytest >= 9.2 no longer reads (the id is ``item._id``, a NodeId): the suffix
    was silently lost, every test was its own unit, and the session fixtures (``small_home``, ``demo_wh``, the clean
    installation of tests/test_install.py, ...) were built once on EACH worker. Here the suffix is added where
    pytest reads it, after xdist's own hook, when that hook did not manage to."""
    if not _is_xdist_worker(config):
        return
    for item in items:
        mark = item.get_closest_marker("xdist_group")
        if mark is None or item.nodeid.endswith(f"@{mark.args[0]}"):
            continue
        nodeid = f"{item.nodeid}@{mark.args[0]}"
        if hasattr(item, "_id"):
            from _pytest.nodeid import NodeId
            item._id = NodeId.parse(nodeid)
        else:                                                            # pytest < 9.2 (xdist's hook did it)
            item._nodeid = nodeid
        if not item.nodeid.endswith(f"@{mark.args[0]}"):
            raise pytest.UsageError(f"could not give {item.nodeid} its xdist group: --dist loadgroup would build "
                                    f"each session fixture on every worker (tests/conftest.py)")


# --- CPU time per test (``--cpu-durations=N``) ---------------------------------------------------------------------
# Wall-clock durations (``--durations``) depend on what else the machine runs; the CPU seconds a test used (its own
# process plus the child processes it started and waited for: runs, pools, servers) do much less. Each phase's CPU
# is attached to its report, so the table also covers tests run by pytest-xdist workers.
def pytest_addoption(parser):
    parser.addoption("--cpu-durations", type=int, default=None, metavar="N",
                     help="list the N tests that used the most CPU time (own process + waited-for children); 0: all")


def _cpu_s() -> float:
    import resource
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


_RUNNING: list = []        # the test whose setup, call or teardown runs now in this process (for shared_data)


def _timed_phase(item):
    t0 = _cpu_s()
    _RUNNING.append(item)
    try:
        yield
    finally:
        _RUNNING.pop()
        item._stridelab_cpu_s = _cpu_s() - t0


pytest_runtest_setup = pytest.hookimpl(wrapper=True)(lambda item: (yield from _timed_phase(item)))
pytest_runtest_call = pytest.hookimpl(wrapper=True)(lambda item: (yield from _timed_phase(item)))
pytest_runtest_teardown = pytest.hookimpl(wrapper=True)(
    lambda item, nextitem: (yield from _timed_phase(item)))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    rep = yield
    cpu = getattr(item, "_stridelab_cpu_s", None)
    if cpu is not None:
        rep.user_properties.append(("cpu_s", round(cpu, 3)))
        item._stridelab_cpu_s = None
    if call.when == "call" and not any(item.get_closest_marker(m) for m in ("slow", "realdata", "browser")):
        rep.user_properties.append(("fast_set", 1))
    return rep


_CPU_BY_TEST: dict[str, float] = {}
_UNMARKED: set[str] = set()        # tests without the slow, realdata and browser markers (those make test-fast runs)
SLOW_CPU_S = 1.0                   # the ``slow`` marker's threshold (pyproject.toml)


def pytest_runtest_logreport(report):
    for k, v in report.user_properties:
        if k == "cpu_s":
            _CPU_BY_TEST[report.nodeid] = _CPU_BY_TEST.get(report.nodeid, 0.0) + v
        elif k == "fast_set":
            _UNMARKED.add(report.nodeid)


def pytest_terminal_summary(terminalreporter, config):
    n = config.getoption("--cpu-durations")
    if n is None or hasattr(config, "workerinput") or not _CPU_BY_TEST:
        return
    rows = sorted(_CPU_BY_TEST.items(), key=lambda kv: -kv[1])
    total = sum(_CPU_BY_TEST.values())
    terminalreporter.write_sep("=", f"CPU time per test (setup + call + teardown), total {total:.0f} s")
    for nodeid, s in rows[:n or None]:
        note = "   (in make test-fast: over the slow marker's 1 s)" if nodeid in _UNMARKED and s > SLOW_CPU_S else ""
        terminalreporter.write_line(f"{s:8.2f}s  {nodeid}{note}")
