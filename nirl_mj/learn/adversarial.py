"""The discriminators of GAIL (Ho & Ermon 2016) and AIRL (Fu, Luo & Levine 2018), on torch.

Both classify state-action pairs as the expert's (label 1) or the learner's (label 0) with the
logistic loss, and hand the policy learner a reward derived from the classifier. Inputs are what
the policy sees of phi(s), ``n_inputs`` values (16 scaled to [0, 1], or 17 in NIRL's bearing code:
``experiments.observation_code``), and the action index 0..5.

- **GAIL**: D(s, a) = sigmoid(l(s, a)), l an MLP with one output per action. The policy's
  reward is -ln(1 - D(s, a)) = softplus(l(s, a)), the form of Ho & Ermon's algorithm 1 with
  the labels as here (expert 1), in (0, inf).
- **AIRL**: D(s, a, s') = exp f(s, a, s') / (exp f(s, a, s') + pi(a | s)), with
  f = g(s, a) + gamma h(s') - h(s) (the shaped form of Fu et al., eq. 4; h(s') = 0 after a
  terminal transition). Its logit is l = f - ln pi(a | s), and the policy's reward is
  ln D - ln(1 - D) = l. The learned reward is g(s, a), one value per action, saved with the run
  like NIRL's r_theta (``AirlDiscriminator.reward``). Fu et al. use a state-only g(s) to
  disentangle the reward from the dynamics; g(s, a) is used here to give one value per action,
  as r_theta does (their state-action variant). With deterministic dynamics g(s, a) may absorb any
  shaping gamma Phi(s') - Phi(s), so only the policy optimal for g over time is pinned down, not
  g's ranking of the actions in one state (tests/test_airl_recovery.py: on a 4 x 4 grid the policy
  optimal for the recovered g(s, a) is the expert's in every cell, while the best action by g alone
  misses it in one of 15 cells for 4 of 5 seeds).

**Absorbing state** (``absorbing=True``; Kostrikov et al. 2019, "Discriminator-Actor-Critic",
section 4.2). Without it an episode's end is worth nothing after its last reward, so a reward that is
negative on the learner's own pairs (AIRL's f - ln pi is) pays the policy to end episodes early: a
collision. With it, a terminal transition leads to an absorbing state s_a that the discriminator
also classifies (one pair (s_a, ., s_a) per terminal episode, expert's and learner's), and the policy
is paid the discounted stay there, gamma / (1 - gamma) times s_a's reward
(``nirl_mj.experiments.adversarial``). As in DAC, the networks read one more input, 1 at s_a and 0
elsewhere (phi is zeros at s_a), so s_a's value moves with the network, not as one slow scalar.
AIRL: f(s, a, s_a) = g(s, a) + gamma h(s_a) - h(s) and f(s_a, ., s_a) = g(s_a, 0) + (gamma - 1) h(s_a);
ln pi = 0 at s_a, which offers one action (a uniform pi over six would pay ln 6 per step for
having ended). Without the option h(s') = 0 after a terminal transition and s_a is never classified:
Fu et al.'s AIRL, unchanged.

**State-only reward** (``state_only=True``, AIRL only): g(s) with one output, Fu et al.'s
disentangled form (their section 5, eq. 4 with g = g(s)); ``reward(x)`` then gives every action the
same g(s), so a reward map is flat across actions.

**Gradient penalty** (:func:`gradient_penalty`): the zero-centred R1 penalty of Mescheder, Geiger &
Nowozin (2018), (lambda / 2) E_expert ||grad_x l||^2 over the expert's pairs in the coded inputs x,
added to the logistic loss. For AIRL the gradient is f's, in both s and s': ln pi(a | s) depends on
s too, but it is the policy's, not the discriminator's to move, so it is left out (strictly R1 of
D would include it). Kostrikov et al. (2019) penalise the discriminator with lambda = 10, but with
Gulrajani et al.'s one-centred penalty, lambda E (||grad|| - 1)^2 with no 1/2, on points interpolated
between expert and learner pairs; that needs an action to interpolate, and ours is one of six, so
the zero-centred penalty on the expert's own pairs is used here, lambda = 10 by default (their
number, not the same coefficient: ours halves it).

Units: logits and rewards are nats; gamma is the policy learner's discount.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from torch.nn import functional

N_INPUTS, N_ACTIONS = 16, 6


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


class Inputs:
    """The networks' inputs: x (N, n_inputs) coded phi(s); with an absorbing state, one more column,
    1 at s_a (``absorbing`` (N,) bool) and 0 elsewhere."""

    def __init__(self, absorbing: bool, n_inputs: int = N_INPUTS) -> None:
        self.absorbing = absorbing
        self.width = n_inputs + int(absorbing)

    def __call__(self, x: torch.Tensor, absorbing: torch.Tensor | None = None) -> torch.Tensor:
        if not self.absorbing:
            if absorbing is not None and bool(absorbing.any()):
                raise ValueError("absorbing pairs given to a discriminator without an absorbing state: "
                                 "make it with absorbing=True")  # fmt: skip
            return x
        marks = torch.zeros(len(x)) if absorbing is None else absorbing.to(x.dtype)
        return torch.cat([x * (1 - marks[:, None]), marks[:, None]], dim=1)

    def absorbing_state(self) -> torch.Tensor:
        """s_a as an input row (1, n_inputs + 1)."""
        row = torch.zeros((1, self.width))
        row[0, -1] = 1.0
        return row


class GailDiscriminator(torch.nn.Module):
    """GAIL's D(s, a) = sigmoid(l(s, a)); ``logits(x, a, x_next, terminal, log_pi, absorbing)`` reads
    x, a and absorbing only."""

    kind = "gail"

    def __init__(
        self, hidden: int = 64, seed: int = 0, absorbing: bool = False, n_inputs: int = N_INPUTS
    ) -> None:
        super().__init__()
        self.inputs = Inputs(absorbing, n_inputs)
        self.net = mlp(self.inputs.width, N_ACTIONS, hidden, torch.Generator().manual_seed(seed))

    def logits(self, x, actions, x_next=None, terminal=None, log_pi=None, absorbing=None) -> torch.Tensor:
        """l(s, a) (N,): x (N, n_inputs) coded phi(s), actions (N,) int; ``absorbing`` (N,) bool marks
        the pairs (s_a, ., s_a) (their x is not read)."""
        return self.net(self.inputs(x, absorbing)).gather(1, actions.long()[:, None])[:, 0]

    @staticmethod
    def policy_reward(logits: torch.Tensor) -> torch.Tensor:
        """-ln(1 - D) = softplus(l) (N,)."""
        return functional.softplus(logits)


class AirlDiscriminator(torch.nn.Module):
    """AIRL's D with f = g(s, a) + gamma h(s') - h(s); the logit l = f - ln pi(a | s)."""

    kind = "airl"

    def __init__(
        self,
        gamma: float,
        hidden: int = 64,
        seed: int = 0,
        absorbing: bool = False,
        state_only: bool = False,
        n_inputs: int = N_INPUTS,
    ) -> None:
        super().__init__()
        generator = torch.Generator().manual_seed(seed)
        self.gamma = float(gamma)
        self.inputs = Inputs(absorbing, n_inputs)
        self.state_only = state_only
        self.g = mlp(self.inputs.width, 1 if state_only else N_ACTIONS, hidden, generator)
        self.h = mlp(self.inputs.width, 1, hidden, generator)

    def f(self, x, actions, x_next, terminal, absorbing=None) -> torch.Tensor:
        """f(s, a, s') (N,); ``terminal`` (N,) bool: s' is s_a, whose h is 0 without an absorbing
        state; ``absorbing`` (N,) bool marks the pairs (s_a, ., s_a)."""
        inputs = self.inputs(x, absorbing)
        g = self.g(inputs)
        g = g[:, 0] if self.state_only else g.gather(1, actions.long()[:, None])[:, 0]
        if self.inputs.absorbing:
            h_next = torch.where(terminal.bool(), self.h(self.inputs.absorbing_state())[0, 0],
                                 self.h(self.inputs(x_next))[:, 0])  # fmt: skip
        else:
            h_next = self.h(x_next)[:, 0] * (~terminal.bool())
        return g + self.gamma * h_next - self.h(inputs)[:, 0]

    def logits(self, x, actions, x_next, terminal, log_pi, absorbing=None) -> torch.Tensor:
        """l = f(s, a, s') - ln pi(a | s) (N,); at s_a, ln pi = 0 (one action)."""
        if absorbing is not None and self.inputs.absorbing:
            log_pi = log_pi * (~absorbing.bool())
        return self.f(x, actions, x_next, terminal, absorbing) - log_pi

    @staticmethod
    def policy_reward(logits: torch.Tensor) -> torch.Tensor:
        """ln D - ln(1 - D) = l (N,)."""
        return logits

    def reward(self, x: np.ndarray) -> np.ndarray:
        """The learned reward g(s, .) (N, 6) in the coded states x (N, n_inputs); a state-only g(s) is
        the same for every action."""
        with torch.no_grad():
            g = self.g(self.inputs(torch.as_tensor(np.asarray(x, dtype=np.float32)))).numpy()
        return np.repeat(g, N_ACTIONS, axis=1) if self.state_only else g


def discriminator_loss(expert_logits: torch.Tensor, learner_logits: torch.Tensor) -> torch.Tensor:
    """The logistic loss, expert pairs labelled 1 and the learner's 0, each side averaged:
    mean softplus(-l_E) + mean softplus(l_pi) = -mean ln D(expert) - mean ln(1 - D(learner))."""
    return functional.softplus(-expert_logits).mean() + functional.softplus(learner_logits).mean()


PENALTY_WEIGHT = 10.0
"""lambda of :func:`gradient_penalty` by default (Kostrikov et al. 2019's weight)."""


def gradient_penalty(
    logits: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
    x: torch.Tensor,
    x_next: torch.Tensor,
    weight: float = PENALTY_WEIGHT,
) -> torch.Tensor:
    """R1: (weight / 2) mean_i ||d l_i / d(x_i, x'_i)||^2 over a batch of expert pairs.
    ``logits(x, x_next)`` (N,) must read x (x_next may go unread, as GAIL's does); x and x_next
    (N, n_inputs) coded phi. The result keeps its graph, for backward()."""
    x, x_next = x.detach().requires_grad_(True), x_next.detach().requires_grad_(True)
    grads = torch.autograd.grad(logits(x, x_next).sum(), [x, x_next], create_graph=True, allow_unused=True)
    squares = sum((g**2).sum(dim=1) for g in grads if g is not None)
    return weight / 2 * squares.mean()


def make_discriminator(
    kind: str,
    gamma: float,
    seed: int = 0,
    absorbing: bool = False,
    state_only: bool = False,
    n_inputs: int = N_INPUTS,
) -> GailDiscriminator | AirlDiscriminator:
    """The discriminator of ``kind`` ("gail" or "airl") on ``n_inputs`` coded values of phi(s), with
    an absorbing state if asked, and for AIRL a state-only g(s) if asked."""
    if kind == "gail":
        if state_only:
            raise ValueError("a state-only reward is AIRL's: GAIL's discriminator reads the action")
        return GailDiscriminator(seed=seed, absorbing=absorbing, n_inputs=n_inputs)
    if kind == "airl":
        return AirlDiscriminator(
            gamma, seed=seed, absorbing=absorbing, state_only=state_only, n_inputs=n_inputs
        )
    raise ValueError(f"unknown discriminator {kind!r}: accepted: gail, airl")
