"""The crossing unit's clock: a batch of fixes fed in reception order with the ticks between them
(:func:`run_controller`), and the wake-ups at the instants a warning falls due (:func:`wake_until`), as a
live unit's clock runs."""

from __future__ import annotations

from collections.abc import Sequence

from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.values import ControllerSettings, CrossingEvent, Fix, TrainSpec
from console.layout import LevelCrossing
from parsers.units import NS


def run_controller(
    crossing: LevelCrossing,
    trains: Sequence[TrainSpec],
    fixes: Sequence[Fix],
    settings: ControllerSettings | None = None,
    tick_s: float | None = None,
    partings: Sequence[tuple[int, str, str]] = (),
) -> CrossingController:
    """Batch: feed fixes in reception order, ticking every ``tick_s`` (default: the settings') between them;
    ``partings`` (time, train, evidence) from the integrity monitor are told to the unit as they come."""
    ctl = CrossingController(crossing, trains, settings)
    ordered = sorted(fixes, key=lambda f: f.t_ns)
    if not ordered:
        return ctl
    tick_s = ctl.s.tick_s if tick_s is None else tick_s
    t = ordered[0].t_ns
    step = max(1, int(tick_s * NS))
    told = sorted(partings)
    for f in ordered:
        if f.t_ns > t:
            wake_until(ctl, _tick(ctl, t, (f.t_ns - t - 1) // step, step), f.t_ns)  # every tick and wake-up before it
        while told and told[0][0] <= f.t_ns:
            ctl.train_parted(told[0][1], told[0][0], told[0][2])
            told.pop(0)
        ctl.step(f)
        t = f.t_ns
    # A live unit keeps its clock running: let pending stale-device alarms fire, and the warning
    # for a train last heard approaching come on when it could be near (it is not forgotten).
    end = max(t + int((ctl.s.stale_after_s + tick_s) * NS), (ctl.next_change_ns() or t) + 2 * step)
    _tick(ctl, t, -(-(end - t) // step), step)
    return ctl


def _tick(ctl: CrossingController, t0_ns: int, n: int, step_ns: int) -> int:
    """``ctl.tick`` at ``t0 + k·step`` for k = 1..n, and at each instant between them when a warning
    comes due (:meth:`CrossingController.next_onset_ns`), as a live unit's clock wakes.

    Ticks stop one tick after nothing a tick does can change until the next fix
    (:meth:`CrossingController.next_change_ns`): every device gone stale and every
    warning due.  So a fix dated years after the one before it (a damaged year) costs
    the stale time's ticks, not one tick per second of the years.  Returns the last instant ticked.
    """
    if n < 1:
        return t0_ns
    settled = ctl.next_change_ns()
    done = t0_ns
    for k in range(1, n + 1):
        t = t0_ns + k * step_ns
        if settled is None or t > settled + 2 * step_ns:  # two ticks past it: the stale time is a float
            return done
        wake_until(ctl, done, t)
        ctl.tick(t)
        done = t
    return done


def wake_until(ctl: CrossingController, from_ns: int, to_ns: int) -> tuple[int, list[CrossingEvent]]:
    """Tick ``ctl`` at each instant in (``from_ns``, ``to_ns``) when something falls due (every driver's
    wake-ups between its steady ticks); returns the last instant ticked (``from_ns`` if none) and the
    events of those ticks."""
    out: list[CrossingEvent] = []
    while (w := ctl.next_onset_ns(from_ns)) is not None and w < to_ns:
        out += ctl.tick(w)
        from_ns = w
    return from_ns, out
