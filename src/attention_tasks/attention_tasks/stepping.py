"""The stepping rules every task's world shares: the random warm-up, checked actions."""

from attention_tasks.task import Step


class SteppedWorld:
    """
    A world stepped by action index.

    A subclass gives ``num_actions``, ``reset`` and ``_advance`` (one action, no checks) and
    keeps ``config.warmup_steps``, ``_rng``, ``_episode`` (-1 before the first reset),
    ``_agent_step`` and ``_needs_reset``.
    """

    num_actions: int

    def reset(self) -> Step:
        """Start the next episode (the subclass's)."""
        raise NotImplementedError

    def _advance(self, action: int) -> Step:
        raise NotImplementedError

    def warm_up(self) -> Step:
        """Take ``warmup_steps`` random actions (seeded); return the step the agent starts from."""
        step = self.reset() if self._episode < 0 else None
        for _ in range(self.config.warmup_steps):
            step = self._advance(int(self._rng.integers(self.num_actions)))
            if step.done:
                step = self.reset()
        return step if step is not None else self.reset()

    def step(self, action: int) -> Step:
        """Apply one agent action; the caller resets after a step that is ``done``."""
        if not 0 <= int(action) < self.num_actions:
            raise ValueError(f'action {action} is out of range 0..{self.num_actions - 1}')
        if self._needs_reset:
            raise RuntimeError('the episode is over (or never began): call reset() first')
        self._agent_step += 1
        return self._advance(int(action))._replace(action=int(action))
