"""The loopback fixtures (:mod:`tests.missions.loopback`)."""

from tests.missions.loopback import fast_policy, no_leaked_threads, spawn_mock

__all__ = ["fast_policy", "no_leaked_threads", "spawn_mock"]
