"""The benchmark harness (runtime against measured error across LOD strategies) and
its reports.
"""

__all__ = ["harness", "report"]
