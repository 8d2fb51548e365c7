"""The discriminators of GAIL (Ho & Ermon 2016) and AIRL (Fu, Luo & Levine 2018), on torch.

Both classify state-action pairs as the expert's (label 1) or the learner's (label 0) with the
logistic loss, and hand the policy learner a reward derived from the classifier. Inputs are
phi(s) scaled to [0, 1] (16 values, as the RL reference sees them) and the action index 0..5.

- **GAIL**: D(s, a) = sigmoid(l(s, a)), l an MLP with one output per action. The policy's
  reward is -ln(1 - D(s, a)) = softplus(l(s, a)), the form of Ho & Ermon's algorithm 1 with
  the labels as here (expert 1), in (0, inf).
- **AIRL**: D(s, a, s') = exp f(s, a, s') / (exp f(s, a, s') + pi(a | s)), with
  f = g(s, a) + gamma h(s') - h(s) (the shaped form of Fu et al., eq. 4; h(s') = 0 after a
  terminal transition). Its logit is l = f - ln pi(a | s), and the policy's reward is
  ln D - ln(1 - D) = l. The learned reward is g(s, a), one value per action, saved with the run
  like NIRL's r_theta (``AirlDiscriminator.reward``). Fu et al. use a state-only g(s) to
  disentangle the reward from the dynamics; g(s, a) is used here so that the reward ranks the six
  actions in a state as r_theta does (their state-action variant).

**Absorbing state** (``absorbing=True``; Kostrikov et al. 2019, "Discriminator-Actor-Critic",
section 4.2). Without it an episode's end is worth nothing after its last reward, so a reward that is
negative on the learner's own pairs (AIRL's f - ln pi is) pays the policy to end episodes early: a
collision. With it, a terminal transition leads to an absorbing state s_a that the discriminator
also classifies (one pair per terminal episode, expert's and learner's), and the policy is paid the
discounted stay there, gamma / (1 - gamma) times s_a's reward (``nirl_mj.experiments.adversarial``).
Here s_a is one learned value, not an input: GAIL's logit at s_a is a scalar; AIRL's f reads
scalars g(s_a) and h(s_a): f(s, a, s_a) = g(s, a) + gamma h(s_a) - h(s) and
f(s_a, ., s_a) = g(s_a) + (gamma - 1) h(s_a), and ln pi = 0 there: s_a offers one action, no
choice, so no entropy (a uniform pi over six would pay ln 6 per step for having ended).
Without the option h(s_a) = 0 and s_a is never classified: Fu et al.'s AIRL, unchanged.

Units: logits and rewards are nats; gamma is the policy learner's discount.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.nn import functional

N_INPUTS, N_ACTIONS = 16, 6
ABSORBING = "absorbing"  # the name of the absorbing state's parameters (and of their saved array)


def mlp(n_in: int, n_out: int, hidden: int, generator: torch.Generator) -> torch.nn.Sequential:
    """n_in -> hidden -> hidden -> n_out, tanh hidden units, initialised from ``generator``."""
    linear, tanh = torch.nn.Linear, torch.nn.Tanh
    layers = [linear(n_in, hidden), tanh(), linear(hidden, hidden), tanh(), linear(hidden, n_out)]
    with torch.no_grad():
        for layer in layers:
            if isinstance(layer, torch.nn.Linear):
                bound = 1.0 / np.sqrt(layer.in_features)
                layer.weight.copy_(torch.rand(layer.weight.shape, generator=generator) * 2 * bound - bound)
                layer.bias.zero_()
    return torch.nn.Sequential(*layers)


class GailDiscriminator(torch.nn.Module):
    """GAIL's D(s, a) = sigmoid(l(s, a)); ``logits(x, a, x_next, terminal, log_pi, absorbing)`` reads
    x, a and absorbing only. With ``absorbing``, ``self.absorbing`` (1,) is the logit at s_a."""

    kind = "gail"

    def __init__(self, hidden: int = 64, seed: int = 0, absorbing: bool = False) -> None:
        super().__init__()
        self.net = mlp(N_INPUTS, N_ACTIONS, hidden, torch.Generator().manual_seed(seed))
        if absorbing:
            self.absorbing = torch.nn.Parameter(torch.zeros(1))

    def logits(self, x, actions, x_next=None, terminal=None, log_pi=None, absorbing=None) -> torch.Tensor:
        """l(s, a) (N,): x (N, 16) scaled phi(s), actions (N,) int; ``absorbing`` (N,) bool marks
        the pairs (s_a, ., s_a), whose x and a are not read."""
        logits = self.net(x).gather(1, actions.long()[:, None])[:, 0]
        return _at_absorbing(self, logits, absorbing, lambda p: p[0])

    @staticmethod
    def policy_reward(logits: torch.Tensor) -> torch.Tensor:
        """-ln(1 - D) = softplus(l) (N,)."""
        return functional.softplus(logits)


class AirlDiscriminator(torch.nn.Module):
    """AIRL's D with f = g(s, a) + gamma h(s') - h(s); the logit l = f - ln pi(a | s).
    With ``absorbing``, ``self.absorbing`` (2,) holds (g(s_a), h(s_a))."""

    kind = "airl"

    def __init__(self, gamma: float, hidden: int = 64, seed: int = 0, absorbing: bool = False) -> None:
        super().__init__()
        generator = torch.Generator().manual_seed(seed)
        self.gamma = float(gamma)
        self.g = mlp(N_INPUTS, N_ACTIONS, hidden, generator)
        self.h = mlp(N_INPUTS, 1, hidden, generator)
        if absorbing:
            self.absorbing = torch.nn.Parameter(torch.zeros(2))

    def f(self, x, actions, x_next, terminal, absorbing=None) -> torch.Tensor:
        """f(s, a, s') (N,); ``terminal`` (N,) bool: s' is s_a, h(s') = h(s_a) (0 without the
        option); ``absorbing`` (N,) bool marks the pairs (s_a, ., s_a)."""
        g = self.g(x).gather(1, actions.long()[:, None])[:, 0]
        h_next = torch.where(terminal.bool(), self._h_absorbing(), self.h(x_next)[:, 0])
        f = g + self.gamma * h_next - self.h(x)[:, 0]
        return _at_absorbing(self, f, absorbing, lambda p: p[0] + (self.gamma - 1.0) * p[1])

    def _h_absorbing(self) -> torch.Tensor:
        return self.absorbing[1] if hasattr(self, ABSORBING) else torch.zeros(())

    def logits(self, x, actions, x_next, terminal, log_pi, absorbing=None) -> torch.Tensor:
        """l = f(s, a, s') - ln pi(a | s) (N,); at s_a, ln pi = 0 (one action)."""
        log_pi = _at_absorbing(self, log_pi, absorbing, lambda _: torch.zeros(()))
        return self.f(x, actions, x_next, terminal, absorbing) - log_pi

    @staticmethod
    def policy_reward(logits: torch.Tensor) -> torch.Tensor:
        """ln D - ln(1 - D) = l (N,)."""
        return logits

    def reward(self, x: np.ndarray) -> np.ndarray:
        """The learned reward g(s, .) (N, 6) in the scaled states x (N, 16)."""
        with torch.no_grad():
            return self.g(torch.as_tensor(np.asarray(x, dtype=np.float32))).numpy()


def _at_absorbing(discriminator: torch.nn.Module, values: torch.Tensor, absorbing, value) -> torch.Tensor:
    """``values`` (N,) with the rows marked in ``absorbing`` (N,) bool replaced by
    ``value(discriminator.absorbing)``; unchanged without absorbing rows. A discriminator without
    the option refuses them."""
    if absorbing is None or not bool(absorbing.any()):
        return values
    if not hasattr(discriminator, ABSORBING):
        raise ValueError("absorbing pairs given to a discriminator without an absorbing state: "
                         "make it with absorbing=True")  # fmt: skip
    return torch.where(absorbing.bool(), value(discriminator.absorbing).to(values.dtype), values)


def discriminator_loss(expert_logits: torch.Tensor, learner_logits: torch.Tensor) -> torch.Tensor:
    """The logistic loss, expert pairs labelled 1 and the learner's 0, each side averaged:
    mean softplus(-l_E) + mean softplus(l_pi) = -mean ln D(expert) - mean ln(1 - D(learner))."""
    return functional.softplus(-expert_logits).mean() + functional.softplus(learner_logits).mean()


def make_discriminator(
    kind: str, gamma: float, seed: int = 0, absorbing: bool = False
) -> GailDiscriminator | AirlDiscriminator:
    """The discriminator of ``kind`` ("gail" or "airl"), with an absorbing state if asked."""
    if kind == "gail":
        return GailDiscriminator(seed=seed, absorbing=absorbing)
    if kind == "airl":
        return AirlDiscriminator(gamma, seed=seed, absorbing=absorbing)
    raise ValueError(f"unknown discriminator {kind!r}: accepted: gail, airl")
