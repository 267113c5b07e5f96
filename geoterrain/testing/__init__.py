"""Independent measures and reference oracles, which tests and benchmarks check the
pipeline against (the pipeline never imports them).
"""

__all__ = ["measure", "metricmeasure", "reference"]
