"""The analysis: records → results → statistics.

``results`` reads and selects records into tables; ``correlation`` correlates each metric with
RL return (intervals, multiple-testing corrections); ``claims`` judges the paper's claims with
rules fixed in code; ``calibration`` predicts an encoder's return from its metrics.
"""
