"""The pipeline: `frictionuq run WORKFLOW [TARGET ...]` (plan -> cache -> runner, tasks calling
the library; see plan.py for the task graph and the cache keys)."""
from .plan import STAGES, TARGETS, plan
from .runner import RunResult, clean, plan_status, run

__all__ = ["STAGES", "TARGETS", "plan", "RunResult", "clean", "plan_status", "run"]
