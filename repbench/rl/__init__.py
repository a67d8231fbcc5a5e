"""Downstream RL on frozen encoders (Stable-Baselines3)."""
