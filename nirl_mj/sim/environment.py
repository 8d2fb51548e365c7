"""The composer Environment of this project: composer's own, with a cheaper observation schedule.

The navigation task reports one physics step per control step (``nirl_mj.sim.task``), and
composer plans observation updates for that case along its general path (update
intervals, delays, buffers: schedule ahead, then prune), about 50 us per decision for
the task's 11 observables, 5-10 % of a planar-drive decision. When every enabled
observable is plain (buffer of 1, updated every step, no delay), the plan is one
update at the next step; :class:`EveryStepUpdater` writes exactly that entry, so the
buffers receive the same values at the same timestamps and the observations are the
same. Any other observable setting takes composer's path.
"""

from __future__ import annotations

from dm_control import composer
from dm_control.composer import observation
from dm_control.composer.observation import updater as composer_updater


class EveryStepUpdater(observation.Updater):
    """composer's ``observation.Updater`` with a direct schedule for plain observables.

    Reads composer internals (``_enabled_list``, ``_step_counter``; checked against
    dm-control 1.0.50); tests/test_task.py compares the observations with composer's own.
    """

    _plain = False  # until reset: composer's path, which raises its own errors

    def reset(self, physics, random_state) -> None:
        super().reset(physics, random_state)
        self._plain = self._physics_steps_per_control_step == 1 and all(
            e.update_interval == composer_updater.DEFAULT_UPDATE_INTERVAL
            and e.delay == composer_updater.DEFAULT_DELAY
            and e.buffer_size == 1
            for e in self._enabled_list
        )

    def prepare_for_next_control_step(self) -> None:
        if not self._plain:
            super().prepare_for_next_control_step()
            return
        upcoming = (self._step_counter + 1, composer_updater.DEFAULT_DELAY)
        for enabled in self._enabled_list:
            # Already there if a physics error cut the last step short: never twice.
            if not enabled.update_schedule or enabled.update_schedule[-1][0] < upcoming[0]:
                enabled.update_schedule.append(upcoming)


class Environment(composer.Environment):
    """``composer.Environment`` with :class:`EveryStepUpdater` (same observations, less overhead)."""

    def _make_observation_updater(self) -> observation.Updater:
        pad = self._delayed_observation_padding == composer.ObservationPadding.INITIAL_VALUE
        return EveryStepUpdater(
            self._task.observables,
            self._task.physics_steps_per_control_step,
            self._strip_singleton_obs_buffer_dim,
            pad,
        )

    def close(self) -> None:
        """Frees the physics; a second call does nothing (composer's own raises AttributeError)."""
        if self._physics is not None:
            super().close()
