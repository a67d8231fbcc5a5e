"""Built-in encoder plugins for repbench (installed as ``repbench_encoders``)."""
