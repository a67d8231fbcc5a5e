"""The pipeline: a suite file becomes a plan of stages, run by an executor, stored.

``suite`` (the TOML schema) → ``plan`` (the stage graph: datasets → encoders → latents →
metrics → RL) → ``executors`` (local process pool or Ray) running ``stages`` against the
content-addressed ``store``, each stage writing a ``records`` JSON; ``runner`` ties them
together for ``repbench run``, ``evaluate`` for ``repbench evaluate``; ``preflight`` and
``diskfull`` check a run's inputs and its disk before and while it runs.
"""
