"""Benchmark the cost of events and faults in the master. Prints, for bs-3, the
stepping loop's wall clock with a timeline against the plain loop in the same process, as
ratios (best of ``--repeat`` interleaved runs):

* an event at the stop time (the event loop runs, nothing fires until the end);
* a gain fault of 1.0 over the whole run on plant.tunnel_force (delivered every step);
* 500 events at the stop time (a point looks only at the events due at it: about the
  ratio of one event);

and the plain loop's own figure, so a change to it shows. A scenario without events or
faults runs the same loop (``cosim.engine.master._loop``) with no-op calls: its cost is the
baseline.
Usage: ``python scripts/bench_events.py [--stop-time 20] [--repeat 3] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from cosim.engine import master
from cosim.paths import DEFAULT_FMU_DIR
from cosim.scenario.spec import SCENARIO_FOLDER, scenario_from_toml

VARIANTS = {
    "plain": "",
    "event at the stop time": (
        '\n[[events]]\ntime = {stop_time}\nset = {{ "controller.yaw_setpoint" = 0.1 }}\n'
    ),
    "gain fault every step": (
        '\n[[faults]]\nkind = "gain"\ntarget = "plant.tunnel_force"\nvalue = 1.0\n'
    ),
    "500 events at the stop time": "".join(
        f'\n[[events]]\nname = "e{i}"\ntime = {{stop_time}}\n'
        f'set = {{{{ "controller.yaw_setpoint" = 0.1 }}}}\n'
        for i in range(500)
    ),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stop-time", type=float, default=20.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", f"stop_time = {args.stop_time}")
    scenarios = {
        name: scenario_from_toml(
            text + extra.format(stop_time=args.stop_time), name, SCENARIO_FOLDER, args.fmu_dir
        )
        for name, extra in VARIANTS.items()
    }
    best = {name: float("inf") for name in scenarios}
    for _ in range(args.repeat):
        for name, scenario in scenarios.items():
            result = master.run(scenario, keep_rows=False)
            best[name] = min(best[name], result.wall_clock_s)
    steps = scenarios["plain"].n_steps
    print(f"bs-3, {steps} steps, best of {args.repeat}:")
    print(f"  plain loop: {best['plain']:.3f} s ({1e6 * best['plain'] / steps:.0f} us/step)")
    for name in list(VARIANTS)[1:]:
        print(f"  {name}: {best[name]:.3f} s, ratio to plain {best[name] / best['plain']:.3f}")


if __name__ == "__main__":
    main()
