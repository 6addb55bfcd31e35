"""The Foxglove layout shipped with Zarco (``zarco-layout.json`` beside this
module): the map of the boat and the AUV, the boat–AUV distance, the courses,
the mode and track status, and the events.  It names only the topics a
recording and ``zarco shore foxglove`` share (the primary vessel's bare
names), so the same layout opens a recording and a live boat.

Built with Foxglove's own layout types (``foxglove.layouts``); the shipped file
is what :func:`layout_json` returns (a test keeps them equal):

    zarco shore foxglove --save-layout zarco-layout.json
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

LAYOUT_FILE = Path(__file__).with_name("zarco-layout.json")

#: every topic the layout shows
TOPICS = ("/foxglove/vessel", "/foxglove/auv", "/shore/state", "/shore/auv", "/foxglove/events")


def build() -> Any:
    """The layout (a ``foxglove.layouts.Layout``)."""
    import foxglove.layouts as fl

    def plot(title: str, series: list[tuple[str, str, str]], unit: str) -> Any:
        return fl.PlotPanel(title=title, config=fl.PlotConfig(
            paths=[fl.PlotSeries(value=v, label=label, color=color,
                                 timestamp_method="receiveTime")
                   for v, label, color in series],
            show_legend=True, legend_display="top", y_axis_label=unit,
            x_axis_val="timestamp", time_window_mode="automatic"))

    mapp = fl.MapPanel(title="boat and AUV", config=fl.MapConfig(
        follow_topic="/foxglove/vessel", layer="map", zoom_level=18,
        topic_colors={"/foxglove/vessel": "#1a66ff", "/foxglove/auv": "#ff4d1a"},
        topic_config={
            "/foxglove/vessel": fl.MapTopicSettings(history_mode="previous",
                                                    point_display_mode="dot", point_size=4),
            "/foxglove/auv": fl.MapTopicSettings(history_mode="previous",
                                                 point_display_mode="dot", point_size=5)}))
    distance = plot("boat – AUV distance", [("/shore/auv.distance_m", "distance", "#ff4d1a")],
                    "m")
    course = plot("courses", [("/shore/auv.course_deg", "AUV course", "#ff4d1a"),
                              ("/shore/state.course_deg", "boat course", "#1a66ff")], "deg")
    states = fl.StateTransitionsPanel(title="mode and AUV track", config=fl.StateTransitionsConfig(
        paths=[fl.StateTransitionsSeries(value="/shore/state.mode", label="mode"),
               fl.StateTransitionsSeries(value="/shore/auv.status", label="AUV track"),
               fl.StateTransitionsSeries(value="/shore/state.armed", label="armed")],
        show_points=True))
    events = fl.LogPanel(title="events", config=fl.LogConfig(
        topic_to_render="/foxglove/events", show_level=True, show_time=True, show_name=True))
    side = fl.SplitContainer(direction="column", items=[
        fl.SplitItem(proportion=1, content=distance),
        fl.SplitItem(proportion=1, content=course),
        fl.SplitItem(proportion=1, content=states),
        fl.SplitItem(proportion=1.4, content=events)])
    return fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=3, content=mapp), fl.SplitItem(proportion=2, content=side)]))


def layout_json() -> str:
    """The layout as the file holds it (indented JSON, a final newline)."""
    return json.dumps(json.loads(build().to_json()), indent=2, sort_keys=True) + "\n"


def topics_named(obj: Any) -> set[str]:
    """Every topic a layout (parsed JSON) refers to, message paths cut at the field."""
    out: set[str] = set()
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(v, str) and v.startswith("/") and k in (
                    "value", "followTopic", "topicToRender"):
                out.add(v.split(".", 1)[0])
            if k in ("topicColors", "topicConfig") and isinstance(v, dict):
                out.update(v)
            out |= topics_named(v)
    elif isinstance(obj, list):
        for v in obj:
            out |= topics_named(v)
    return out
