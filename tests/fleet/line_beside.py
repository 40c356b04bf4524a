"""A line run with a driver beside it (a twin, a ROS or Foxglove client): the driver works from a thread of its own
with the launcher (its logins, its scene) and a dict to say what it saw, and ends the line when it is done (or the
line's duration does)."""

import threading
from collections.abc import Callable

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.test_run import assert_nothing_left


def run_beside(options: RunOptions, driver: Callable[..., None], *args: object) -> tuple[dict, dict, Launcher]:
    """The run's summary, what `driver(launcher, *args, seen)` put in `seen`, and the launcher; nothing is left
    running (`assert_nothing_left`), and a driver's exception is in `seen["error"]`."""
    seen: dict = {}

    def work(launcher: Launcher) -> None:
        try:
            driver(launcher, *args, seen)
        except BaseException as exc:  # the test reports it
            seen["error"] = repr(exc)
        finally:
            launcher.interrupted = "the driver is done"

    with Launcher(options) as launcher:
        thread = threading.Thread(target=work, args=(launcher,), daemon=True)
        thread.start()
        summary = launcher.run()
        thread.join(60)
    assert_nothing_left(summary, launcher.endpoint)
    return summary, seen, launcher
