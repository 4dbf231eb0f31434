"""Suite-wide settings that must be in place before any test module imports its libraries."""

import atexit
import os
import shutil
import signal
import tempfile

# Every Ray process the suite starts (a local instance, ray.cluster_utils' multi-node clusters, and the
# train-foam subprocesses that join them) binds and connects on the loopback interface only. On Linux,
# Ray picks the host's outward-facing address unless this flag, read once when Ray is imported, says
# "no multi-node `ray start`" (the suite's clusters are built by cluster_utils, which it does not affect).
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")


def _session_compilation_cache() -> None:
    """Point JAX's persistent compilation cache at a fresh directory for this test session.

    Many tests, and the CLI subprocesses that the README/docs examples and CLI tests start, compile the
    same PPO programs again; with the cache each is compiled once per session and read back afterwards.
    JAX reads these variables when it is imported, and subprocesses (and pytest-xdist's workers) inherit
    them, so they all share one directory. It starts empty (a clean clone measures the same) and is
    removed at exit: nothing leaks to ~/.cache, and `jaxsimrl solve`'s own cache there
    (jaxsimrl/apps/foam/cli/solve.py) is neither read nor written. A cached program is the one compiled, so
    results do not change (tests/test_ppo_training.py compares metrics exactly).
    """
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the controller has set it up; share its directory
        return
    cache = tempfile.mkdtemp(prefix="jaxsimrl-tests-xla-")
    atexit.register(shutil.rmtree, cache, ignore_errors=True)
    os.environ["JAX_COMPILATION_CACHE_DIR"] = cache
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"  # default 1 s: most of ours are less


def _quick_xla_compiles() -> None:
    """Compile the session's XLA programs for the CPU with LLVM's optimisation off (-O0).

    Most of the suite's JAX time is compiling small, short-lived programs, not running them: on a
    loaded 2-core machine, back to back (2026-12-02), -O0 cut test_ppo_components.py + test_ppo_training.py
    from 163 s to 117 s of CPU and the README's tour from 68 s to 54 s, all passing. Results stay
    deterministic (the suite compares programs compiled in one session, so compiled alike), but may
    differ in the last bits from -O2 builds, which users get. Inherited like the cache above;
    subprocesses that set their own XLA_FLAGS append to these (tests/test_ppo_devices.py). A flag
    already in XLA_FLAGS wins (`XLA_FLAGS=--xla_backend_optimization_level=2 pytest` tests user builds).
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "--xla_backend_optimization_level" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_backend_optimization_level=0".strip()


def _ctrl_c_delivered() -> None:
    """Let Ctrl-C reach the suite and the processes it starts, even when its shell ignored it.

    A shell without job control starts a background command (`pytest ... &`) with SIGINT ignored, and
    Python then installs no KeyboardInterrupt handler; the children inherit the ignore. The tests of
    Ctrl-C handling (tests/test_runs.py, test_resume.py, test_solve.py) would then see a signal that is
    never delivered: measured 2026-12-02, 2 of them failed in a suite started with `nohup ... &`.
    Undoing it here (controller and each xdist worker import this file) restores what a terminal gives.
    """
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


_session_compilation_cache()
_quick_xla_compiles()
_ctrl_c_delivered()
