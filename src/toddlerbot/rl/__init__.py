"""Reinforcement-learning locomotion (MJX environment, Brax PPO training, export).

Everything here needs the ``[train]`` extra (JAX, MJX, Brax) except ``config``, ``reference`` (tables are built
with numpy) and ``tracking`` (CPU evaluation). The runtime's numpy inference lives in
``toddlerbot.policies.rl_inference``.
"""
