"""`trackside station`: the live station view (Textual).

One screen: the track diagram on top, the sections and trains panels, the
event log and the selected train's speed.  A timer every 0.1 s asks a thread
worker to advance the model (the simulator or a replay) by the wall time
times the playback speed, then the views are redrawn from one snapshot on
the UI thread.  Tests drive :class:`StationApp` with Pilot and step the model
by hand (``app.advance``).
"""

from __future__ import annotations

from typing import ClassVar

from textual import work
from textual.app import App, ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal
from textual.widgets import Header

from console.analysis.timefmt import display
from console.tui.help import HelpScreen
from console.tui.model import Snapshot, StationModel
from console.tui.replay_source import ReplaySource
from console.tui.sim_source import SimSource
from console.tui.widgets.event_log import EventLog
from console.tui.widgets.key_bar import KeyBar, acts
from console.tui.widgets.pickable_table import PickableTable
from console.tui.widgets.sections_table import SectionsTable
from console.tui.widgets.speed_plot import SpeedPlot
from console.tui.widgets.track import TrackDiagram
from console.tui.widgets.trains_table import TrainsTable

TICK_S = 0.1
FAULT_MINUTES = 5


class StationApp(App[None]):
    """The operator's view of a line, simulated or replayed."""

    TITLE = "trackside station"
    ENABLE_COMMAND_PALETTE = False  # every action has its own key
    CSS = """
    Screen { layout: vertical; }
    #panels { height: 1fr; min-height: 6; }
    #bottom { height: 1fr; min-height: 5; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("space", "pause", "Pause"),
        Binding("plus,equals_sign", "faster", "Faster"),
        Binding("minus", "slower", "Slower"),
        Binding("full_stop", "single_step", "Step"),
        Binding("s", "next_section", "Section"),
        Binding("S", "prev_section", "Prev section", show=False),
        Binding("w", "next_train", "Train"),
        Binding("W", "prev_train", "Prev train", show=False),
        Binding("r", "reset_section", "Reset"),
        Binding("1", "fault('dead_channel')", "Dead ch", show=False),
        Binding("2", "fault('isolated_pulse')", "Pulse", show=False),
        Binding("3", "fault('power_loss')", "Power", show=False),
        Binding("4", "fault('eot_loss')", "EOT loss", show=False),
        Binding("5", "fault('head_loss')", "Head loss", show=False),
        Binding("6", "fault('train_parting')", "Parting", show=False),
        Binding("a", "add_train", "Add train"),
        Binding("v", "truth", "Truth"),
        Binding("f", "log_filter", "Filter"),
        Binding("right_square_bracket", "jump(300)", "+5 min", show=False),
        Binding("left_square_bracket", "jump(-300)", "-5 min", show=False),
        Binding("question_mark", "help", "Help"),
        Binding("q", "quit", "Quit"),
    ]

    def __init__(self, model: StationModel, *, autoplay: bool = True) -> None:
        super().__init__()
        self.model = model
        self.autoplay = autoplay
        self._busy = False

    # -- layout ---------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        yield TrackDiagram(self.model.source.layout, id="track")
        with Horizontal(id="panels"):
            yield SectionsTable(id="sections")
            yield TrainsTable(id="trains")
        with Horizontal(id="bottom"):
            yield EventLog(id="log")
            yield SpeedPlot(id="speed")
        yield KeyBar(self.model.source.mode)

    def on_mount(self) -> None:
        self.refresh_views()
        if self.autoplay:
            self.set_interval(TICK_S, self._on_tick)

    # -- the clock --------------------------------------------------------------
    def _on_tick(self) -> None:
        if not self.model.paused and not self._busy:
            self._busy = True
            self._advance_worker(TICK_S)

    @work(thread=True, exclusive=True, group="advance")
    def _advance_worker(self, wall_s: float) -> None:
        try:
            self.model.tick(wall_s)
        finally:
            self.call_from_thread(self._after_advance)

    def _after_advance(self) -> None:
        self._busy = False
        # A tick in flight can end while the app shuts down, after its widgets are gone: nothing to draw then.
        if self.is_running:
            self.refresh_views()

    def advance(self, sim_s: float) -> None:
        """Advance the model by simulated seconds and redraw (tests, single step)."""
        self.model.step(sim_s)
        self.refresh_views()

    # -- drawing -----------------------------------------------------------------
    def refresh_views(self) -> None:
        m = self.model
        snap = m.snapshot()
        diffs = m.differences(snap) if m.show_truth else set()
        self.sub_title = self.subtitle(snap)
        section, train = m.section_id(), m.train_id(snap)
        self.query_one(TrackDiagram).render_snapshot(snap, section, train, diffs)
        self.query_one(SectionsTable).render_snapshot(snap, section, diffs)
        self.query_one(TrainsTable).render_snapshot(snap, train, diffs)
        self.query_one(EventLog).render_entries(m.visible_log(), m.log_filter)
        self.query_one(SpeedPlot).show(
            train, list(m.speed_history.get(train, [])) if train else [], m.source.layout.line_speed_mps * 3.6
        )

    def subtitle(self, snap: Snapshot) -> str:
        """The header's second line (a change of it re-lays out the screen: the live view keeps it steady)."""
        state = "paused" if snap.paused else f"{snap.speed}×"
        mode = "replay" if snap.mode == "replay" else "simulation"
        truth = " · truth view" if self.model.show_truth else ""
        return f"{mode} · {display(snap.time_ns)[:19]} · {state}{truth}"

    # -- actions --------------------------------------------------------------------
    def action_pause(self) -> None:
        self.model.toggle_pause()
        self.refresh_views()

    def action_faster(self) -> None:
        self.model.faster()
        self.refresh_views()

    def action_slower(self) -> None:
        self.model.slower()
        self.refresh_views()

    def action_single_step(self) -> None:
        self.advance(1.0)

    def action_next_section(self) -> None:
        self.model.select_section(1)
        self.refresh_views()

    def action_prev_section(self) -> None:
        self.model.select_section(-1)
        self.refresh_views()

    def action_next_train(self) -> None:
        self.model.select_train(1)
        self.refresh_views()

    def action_prev_train(self) -> None:
        self.model.select_train(-1)
        self.refresh_views()

    def on_pickable_table_picked(self, event: PickableTable.Picked) -> None:
        """A click (or enter) on a row selects that section or train."""
        if isinstance(event.table, SectionsTable):
            ids = [s.id for s in self.model.source.layout.sections]
            if event.key in ids:
                self.model.selected_section = ids.index(event.key)
        elif isinstance(event.table, TrainsTable):
            ids = [t.id for t in self.model.source.trains()]
            if event.key in ids:
                self.model.selected_train = ids.index(event.key)
        self.refresh_views()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Keys that do nothing in this mode (faults in a replay, speed in a live view) are off, and not shown."""
        model = getattr(self, "model", None)
        return True if model is None else acts(action, model.source.mode)

    def action_reset_section(self) -> None:
        sid = self.model.section_id()
        src = self.model.source
        if sid is None or not isinstance(src, SimSource):
            self.notify("resets are for the simulated line", severity="warning")
            return
        # Decided in time order with the detections: the verdict, with its reason, follows in the log.
        src.reset(sid)
        self.model.note("info", f"section {sid}: reset requested")
        self.notify(f"{sid}: reset requested; the verdict follows in the log")
        self.refresh_views()

    def action_fault(self, kind: str) -> None:
        src = self.model.source
        if not isinstance(src, SimSource):
            self.notify("faults are injected into the simulated line", severity="warning")
            return
        if kind in ("eot_loss", "head_loss", "train_parting"):
            target = self.model.train_id()
            if target is None:
                self.notify("no train to fail", severity="warning")
                return
            src.inject(kind, target)
        else:
            sid = self.model.section_id()
            if sid is None:
                return
            section = next(s for s in src.layout.sections if s.id == sid)
            target = section.heads[0]
            src.inject(kind, target, FAULT_MINUTES * 60 if kind == "power_loss" else None)
        what = kind.replace("_", " ")
        self.model.note("warning", f"fault injected: {what} at {target}")
        self.notify(f"fault: {what} at {target}", severity="warning")
        self.refresh_views()

    def action_add_train(self) -> None:
        src = self.model.source
        if not isinstance(src, SimSource):
            return
        self.model.note("info", src.add_train())
        self.refresh_views()

    def action_truth(self) -> None:
        if not isinstance(self.model.source, SimSource):
            self.notify("a replay has no truth", severity="warning")
            return
        self.model.show_truth = not self.model.show_truth
        self.refresh_views()

    def action_log_filter(self) -> None:
        self.model.cycle_log_filter()
        self.refresh_views()

    def action_jump(self, seconds: int) -> None:
        src = self.model.source
        if isinstance(src, ReplaySource):
            # What the jump passed over reaches the log (section changes, crossings), a note first.
            self.model.note("info", f"jumped {'forward' if seconds > 0 else 'back'} {abs(seconds) // 60} min")
            self.model.record(*src.jump(seconds))
        else:
            self.model.step(max(0, seconds))
        self.refresh_views()

    def action_help(self) -> None:
        self.push_screen(HelpScreen())
