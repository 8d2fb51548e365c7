"""Methods from other packages: the ``nirl_mj.methods`` entry point group and its Gymnasium adapter.

A package adds a method by naming an object in its ``pyproject.toml``::

    [project.entry-points."nirl_mj.methods"]
    KNN = "knn_method:KNN"

``KNN`` is then a method name like ``NIRL`` in every experiment file (``methods = ["NIRL", "KNN"]``)
and suite. The object (a class or a factory function, called with the method's ``settings`` as
keyword arguments, or an instance, which takes none) has, in plain Python, NumPy and Gymnasium
types (docs/EXTENDING.md):

- ``reads``: what it reads, words of ``nirl_mj.experiments.reads.VOCABULARY`` (a learner from
  demonstrations: ``["demonstrations", "features", "episode_end"]``, or without ``episode_end`` if
  it never drives the environment);
- ``observation``: ``"features"`` (phi(s), float32 (16,), as ``gymnasium.make("nirl_mj/Navigate-v0",
  observation="features")`` gives it);
- ``train(demonstrations, make_env, budget, seed, workdir) -> policy``: ``demonstrations`` a dict of
  arrays (``observations`` (N, 16) float32, ``actions`` (N,) int64, ``next_observations`` (N, 16),
  ``episode`` (N,) int64, ``terminals`` (N,) bool: the episode ended there by arrival, collision or
  physics error), None unless ``reads`` holds ``demonstrations``; ``make_env()`` a Gymnasium
  environment on the run's training arenas, refused unless ``reads`` holds ``episode_end``;
  ``budget`` the decisions it may drive in all its environments together; ``workdir`` a directory of
  its own, shared by every cell that trains the method for the run and never emptied (a method must
  not resume from it: each attempt trains from scratch on its whole budget); ``policy(observation) ->
  action`` in 0..5, a function of that observation alone (an error it raises is a :class:`MethodError`).

The protocol keeps the rest (for a method that plays by the interface: one that reaches past the
wrapper, ``env.unwrapped``, is not stopped): the environments draw their arenas from the run's training stream
(a ``reset(seed=S)`` draws the stream's next arena, as Stable-Baselines3 runs do; a test arena is
refused), give no reward and no outcome unless ``reads`` says so, and stop at the budget; the
arenas they drew are checked against the test arenas; the policy is tested by the protocol. A method
that breaks a rule raises :class:`MethodError`, one line naming the method and the rule, and its
cell is not retried.
"""

from __future__ import annotations

import functools
import inspect
import os
import sys
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from nirl_mj.data.lock import DirectoryLock
from nirl_mj.sim.spec import SpecError

GROUP = "nirl_mj.methods"
OBSERVATIONS = ("features",)
TRAIN_ARGUMENTS = ("demonstrations", "make_env", "budget", "seed", "workdir")
"""The keyword arguments a method's ``train`` is called with."""
TRAIN_SIGNATURE = f"train({', '.join(TRAIN_ARGUMENTS)})"


class MethodError(SpecError):
    """A method broke the protocol's rules (a test arena asked for, the budget exceeded, a policy of
    the wrong shape, a bad declaration). Deterministic: its cell is not retried."""


def discovered() -> dict[str, metadata.EntryPoint]:
    """Every installed method of the ``nirl_mj.methods`` group, by name (the first of a name that two
    packages provide: :func:`provider` refuses such a name when it is used)."""
    found: dict[str, metadata.EntryPoint] = {}
    for ep in metadata.entry_points(group=GROUP):
        found.setdefault(ep.name, ep)
    return found


def package_of(ep: metadata.EntryPoint) -> str:
    """The name of the distribution that installs ``ep``."""
    return ep.dist.name if ep.dist is not None else "an unknown package"


def provider(name: str) -> metadata.EntryPoint:
    """The entry point of installed method ``name``; refused when no package provides it, or when two
    do (differently). (``experiments.definition`` refuses one of a built-in method's name.)"""
    eps = [ep for ep in metadata.entry_points(group=GROUP) if ep.name == name]
    if not eps:
        raise MethodError(f"method {name!r}: no installed package provides it (entry point group {GROUP}; "
                          f"installed: {', '.join(discovered()) or 'none'})")  # fmt: skip
    distinct = {(package_of(ep), ep.value) for ep in eps}  # one package seen twice on the path is one
    if len(distinct) > 1:
        raise MethodError(f"method {name!r}: several packages provide it ("
                          f"{'; '.join(f'{pkg}: {value}' for pkg, value in sorted(distinct))}); "
                          "uninstall or rename all but one")  # fmt: skip
    return eps[0]


def version_of(name: str) -> str:
    """``DISTRIBUTION VERSION`` of the package that provides method ``name`` (in an experiment's
    identity: another version of a method is another computation)."""
    dist = provider(name).dist
    return f"{dist.name} {dist.version}" if dist is not None else "unknown"


def source_digest(name: str) -> str:
    """SHA-256 (16 hex digits) of the Python sources of the package that holds method ``name``'s entry
    point (every ``.py`` file of its top-level package, or its one module): in the method's identity,
    so that code edited under an unchanged version (an editable install) is another computation."""
    import hashlib

    top = provider(name).module.partition(".")[0]
    try:  # as a new process finds it (not an earlier import's, in sys.modules): the import path, or
        # an editable install's import hook
        spec = next(
            (found for finder in sys.meta_path if hasattr(finder, "find_spec")
             if (found := finder.find_spec(top, None)) is not None), None
        )  # fmt: skip
    except (ImportError, ValueError) as exc:
        raise MethodError(f"method {name!r}: its module {top!r} cannot be found: {exc}") from None
    if spec is None:
        raise MethodError(f"method {name!r}: its module {top!r} cannot be found")
    if spec.submodule_search_locations:
        roots = [Path(p) for p in spec.submodule_search_locations]
        files = sorted({(f.relative_to(root).as_posix(), f) for root in roots for f in root.rglob("*.py")})
    elif spec.origin and spec.origin.endswith(".py"):
        files = [(Path(spec.origin).name, Path(spec.origin))]
    else:  # compiled or frozen: its version names it
        return "no Python source"
    digest = hashlib.sha256()
    for relative, path in files:
        digest.update(relative.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def load_method(name: str, settings: dict | None = None) -> Any:
    """The method object of entry point ``name``, instantiated with ``settings`` if it is a class;
    its declarations checked."""
    ep = provider(name)
    try:
        target = ep.load()
    except Exception as exc:  # a broken package: one line naming it
        raise MethodError(f"method {name!r}: its entry point {ep.value!r} cannot be loaded: "
                          f"{type(exc).__name__}: {exc}") from None  # fmt: skip
    # a class or a factory function is called with the settings; an object with train() is the method
    made = isinstance(target, type) or (callable(target) and not hasattr(target, "train"))
    if not made and settings:
        raise MethodError(f"method {name!r}: its entry point {ep.value!r} is an instance, which takes no "
                          f"settings (given {settings}); point it at a class or a factory")  # fmt: skip
    try:
        method = target(**(settings or {})) if made else target
    except Exception as exc:  # its own checks of its settings: one line naming the method
        raise MethodError(
            f"method {name!r}: settings {settings or {}}: {type(exc).__name__}: {exc}"
        ) from None
    check_declarations(name, method)
    return method


def check_declarations(name: str, method: Any) -> None:
    """Refuses a method whose ``reads``, ``observation`` or ``train`` is missing or wrong."""
    from nirl_mj.experiments.reads import VOCABULARY, check_words

    reads = getattr(method, "reads", None)
    if not isinstance(reads, list | tuple) or not all(isinstance(w, str) for w in reads):
        given = "it declares none" if reads is None else f"it declares {reads!r} ({type(reads).__name__})"
        raise MethodError(f"method {name!r}: declare `reads`, a list of what it reads, words of "
                          f"{', '.join(VOCABULARY)}; {given}")  # fmt: skip
    try:
        check_words(list(reads), f"method {name!r}")
    except ValueError as exc:
        raise MethodError(str(exc)) from None
    observation = getattr(method, "observation", None)
    if observation not in OBSERVATIONS:
        raise MethodError(
            f"method {name!r}: observation = {observation!r}: accepted: {', '.join(OBSERVATIONS)}"
        )
    if observation not in reads:  # its policy acts on them, and its demonstrations hold them
        raise MethodError(f"method {name!r}: it acts on {observation}: declare {observation} in its reads")
    train = getattr(method, "train", None)
    if not callable(train):
        raise MethodError(f"method {name!r}: it has no {TRAIN_SIGNATURE}")
    try:
        inspect.signature(train).bind(**dict.fromkeys(TRAIN_ARGUMENTS))
    except TypeError as exc:  # called with these keywords: found now, not after the demonstrations
        raise MethodError(f"method {name!r}: its train{inspect.signature(train)} cannot be called as "
                          f"{TRAIN_SIGNATURE} ({exc})") from None  # fmt: skip
    except ValueError:  # a builtin without a signature: it is called as it is
        pass


def demonstration_arrays(trajectories: list) -> dict[str, np.ndarray]:
    """The demonstrations as plain arrays (module docstring): one row per decision (discrete actions)."""
    from nirl_mj.data.trajectory import TERMINAL_OUTCOMES, require_discrete

    require_discrete(trajectories)
    obs, actions, next_obs, episode, terminals = [], [], [], [], []
    for i, t in enumerate(trajectories):
        n = len(t)
        obs.append(np.asarray(t.features[:n], np.float32))
        next_obs.append(np.asarray(t.features[1 : n + 1], np.float32))
        actions.append(np.asarray(t.actions, np.int64))
        episode.append(np.full(n, i, np.int64))
        ends = np.zeros(n, bool)
        if n and t.outcome in TERMINAL_OUTCOMES:
            ends[-1] = True
        terminals.append(ends)
    return {"observations": np.concatenate(obs), "actions": np.concatenate(actions),
            "next_observations": np.concatenate(next_obs), "episode": np.concatenate(episode),
            "terminals": np.concatenate(terminals)}  # fmt: skip


class _Budget:
    """The decisions left to all of a method's environments, and the arenas they drew."""

    def __init__(self, name: str, decisions: int, seed: int, test_seeds: frozenset[int]) -> None:
        from nirl_mj.experiments.seeds import domain_seed
        from nirl_mj.gym.arena_stream import ArenaStream  # no Gymnasium: a method may never drive

        self.name, self.left, self.total = name, decisions, decisions
        self.stream = ArenaStream(functools.partial(domain_seed, "train", seed))
        self._test_seeds = test_seeds
        self._process = os.getpid()

    def _elsewhere(self) -> MethodError:
        return MethodError(
            f"method {self.name!r}: its environments run in this process (a process vector "
            "environment would copy its budget and arenas); use a synchronous one"
        )

    def _here(self) -> None:
        # a forked process vector environment copies the budget and the stream without pickling them
        if os.getpid() != self._process:
            raise self._elsewhere()

    def check_seed(self, seed: int | None) -> None:
        self._here()
        if seed is not None and int(seed) in self._test_seeds:
            raise MethodError(
                f"method {self.name!r} asked for arena {seed}, one of its run's test arenas: "
                "reset() draws the run's training arenas; a method never chooses one"
            )

    def __reduce__(self):
        # a process vector environment would copy the budget and the arena stream into each worker
        # (the budget multiplied, the same arenas drawn, none of them recorded here)
        raise self._elsewhere()

    def spend(self) -> None:
        self._here()
        if self.left <= 0:
            raise MethodError(f"method {self.name!r} drove more than its budget of {self.total} decisions")
        self.left -= 1


def protocol_env(task, budget: _Budget, reads: tuple[str, ...]):
    """The Gymnasium environment a method trains in (module docstring)."""
    import gymnasium

    from nirl_mj.gym.env import NavigationEnv
    from nirl_mj.gym.wrappers import ArenaSeeds

    class ProtocolEnv(gymnasium.Wrapper):
        def reset(self, *, seed: int | None = None, options: dict | None = None):
            budget.check_seed(seed)
            observation, info = self.env.reset(options=options)  # ArenaSeeds draws from the stream
            return observation, (info if "task_outcome" in reads else {})

        def step(self, action):
            budget.spend()
            observation, reward, terminated, truncated, info = self.env.step(action)
            if "task_reward" not in reads:
                reward = 0.0
            if "task_outcome" not in reads:
                info = {}
            return observation, reward, terminated, truncated, info

    env = NavigationEnv(task, observation="features")
    return ProtocolEnv(ArenaSeeds(env, stream=budget.stream, replace_given=True))


def checked_policy(name: str, policy: Any, example: np.ndarray) -> Callable[[np.ndarray], int]:
    """``policy`` as ``phi -> int``, refused (one line naming the method) unless it answers one
    observation with one action in 0..5."""
    from nirl_mj.data.features import N_ACTIONS

    if not callable(policy):
        raise MethodError(f"method {name!r}: train() returned {type(policy).__name__}, not a policy "
                          "(a callable observation -> action)")  # fmt: skip

    def act(phi: np.ndarray) -> int:
        phi = np.asarray(phi, np.float32)
        try:
            answer = np.asarray(policy(phi))
        except (MemoryError, OSError):
            raise  # what another attempt may not meet again, as train's
        except Exception as exc:  # the method's own error: its seeded cell would fail again (not retried)
            raise MethodError(f"method {name!r}: its policy raised {type(exc).__name__}: {exc}; its "
                              "traceback is in the failure's record") from exc  # fmt: skip
        if (
            answer.shape not in ((), (1,))
            or not np.issubdtype(answer.dtype, np.integer)
            or not (0 <= int(answer.reshape(-1)[0]) < N_ACTIONS)
        ):
            raise MethodError(f"method {name!r}: its policy answered an observation of shape {phi.shape} "
                              f"with {answer!r} (shape {answer.shape}); expected one action, an integer in "
                              f"0..{N_ACTIONS - 1}")  # fmt: skip
        return int(answer.reshape(-1)[0])

    act(example)  # refused before the tests start
    return act


def train_plugin(job) -> tuple[Callable[[np.ndarray], int], list[int]]:
    """Trains the plugin method of ``job`` (``nirl_mj.experiments.kinds``): its demonstrations as
    arrays, environments on the run's training arenas, its budget and a work directory; never the
    test arenas. Returns its checked policy and the arenas its environments drew."""
    from nirl_mj.data.dataset import load_dataset
    from nirl_mj.data.trajectory import require_discrete

    name = job.method.plugin
    method = load_method(name, job.method.settings)
    reads = tuple(method.reads)
    trajectories = load_dataset(job.demos_path)
    require_discrete(trajectories, str(job.demos_path))
    demos = demonstration_arrays(trajectories)
    budget = _Budget(job.method.name, job.method.steps, job.seed, frozenset(job.test_seeds))
    workdir = Path(job.run_dir)
    # Not emptied: a sweep's grid cells (and a compare's strip) train the same (method, run) in it,
    # one after the other (the lock below); a method keeps nothing there to resume from (EXTENDING.md)
    workdir.mkdir(parents=True, exist_ok=True)
    made = []

    def make_env():
        if "episode_end" not in reads:  # a driven episode's end is the dynamics it reads
            raise MethodError(f"method {job.method.name!r} drives the robot (make_env): declare "
                              "episode_end in its reads")  # fmt: skip
        try:
            made.append(protocol_env(job.task, budget, reads))
        except ModuleNotFoundError as exc:
            if exc.name != "gymnasium":
                raise
            # a missing package: the executor does not retry it (experiments.executors)
            raise ModuleNotFoundError(
                f"method {job.method.name!r} drives the robot: its environments are Gymnasium's; "
                "install the extra nirl-mj[gym] (pip install -e '.[gym]')",
                name="gymnasium",
            ) from None
        return made[-1]

    given = demos if "demonstrations" in reads else None
    try:
        with DirectoryLock(workdir, f"training of method {job.method.name}", wait=True):
            policy = method.train(demonstrations=given, make_env=make_env, budget=job.method.steps,
                                  seed=job.seed, workdir=str(workdir))  # fmt: skip
    except (MethodError, MemoryError, OSError, ModuleNotFoundError):
        raise  # the protocol's refusals, and what another attempt may not meet again, as they are
    except Exception as exc:
        # the method's own error: its cell is seeded, so another attempt fails the same way (not retried)
        undeclared = given is None and isinstance(exc, TypeError) and "NoneType" in str(exc)
        hint = " (demonstrations=None: they are not in its reads)" if undeclared else ""
        raise MethodError(f"method {job.method.name!r}: train() raised {type(exc).__name__}: {exc}{hint}; "
                          "its traceback is in the failure's record") from exc  # fmt: skip
    finally:
        for env in made:
            env.close()
    return checked_policy(job.method.name, policy, demos["observations"][0]), list(budget.stream.used)
