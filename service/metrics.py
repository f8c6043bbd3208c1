"""Prometheus metrics of the service (prometheus-client), one registry per application.

- ``flycrane_tasks{status=...}``: tasks per status, read from the store at scrape time;
- ``flycrane_planning_seconds``: planner wall time of finished tasks (histogram);
- ``flycrane_task_submissions_total{outcome=accepted|refused|invalid}``.
"""

from __future__ import annotations

from collections.abc import Iterator

from prometheus_client import CollectorRegistry, Counter, Histogram
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector

from service.storage import TaskStore


class _TaskCounts(Collector):
    def __init__(self, store: TaskStore) -> None:
        self.store = store

    def collect(self) -> Iterator[GaugeMetricFamily]:
        family = GaugeMetricFamily("flycrane_tasks", "Tasks per status", labels=["status"])
        for status, count in self.store.counts_by_status().items():
            family.add_metric([status], count)
        yield family


class ServiceMetrics:
    """The instruments of one application."""

    def __init__(self, store: TaskStore) -> None:
        self.registry = CollectorRegistry()
        self.registry.register(_TaskCounts(store))
        self.planning_seconds = Histogram(
            "flycrane_planning_seconds",
            "Planner wall time of finished tasks",
            buckets=(0.5, 1, 2, 5, 10, 20, 30, 60, 120, 300, 600),
            registry=self.registry,
        )
        self.submissions = Counter(
            "flycrane_task_submissions",
            "Task submissions by outcome",
            labelnames=["outcome"],
            registry=self.registry,
        )
