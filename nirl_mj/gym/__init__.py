"""Gymnasium environments of the navigation task (the optional extra ``nirl-mj[gym]``).

``import nirl_mj`` registers ``nirl_mj/Navigate-v0``, ``nirl_mj/Dynamic-v0``, ... (one id per
task file shipped under ``tasks/``) whenever Gymnasium is installed; ``registration`` does it and
stays light (no simulator). ``env`` holds :class:`~nirl_mj.gym.env.NavigationEnv`, an own
adapter over ``nirl_mj.sim.task.make_env`` (docs/GYM.md: why not Shimmy), ``spaces`` the dm_env spec
-> Gymnasium space conversion, ``policies`` experts and reference policies as ``policy(obs) ->
action``, ``minari_export`` datasets as Minari datasets.
"""
