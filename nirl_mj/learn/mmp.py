"""Model-free maximum margin planning (paper section IV-B, Algorithm 1 line 5).

Feature expectations (eq. 3, eq. 11) from trajectories of state-action
features f(s_t, a_t) (eq. 4-5; D = 96 in the paper's layout, but any D works),
and the eq. 13 objective written per state-action pair, minimised by projected
subgradient descent inside the unit ball ||theta||_2 <= 1. Rewards are
r_theta(s, a) = theta^T f(s, a) (eq. 2), in the units of f.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from nirl_mj.data.features import N_ACTIONS
from nirl_mj.learn.config import LoopConfig, MaxMarginConfig
from nirl_mj.learn.reward import trajectory_pair_features

__all__ = [
    "discounted_suffix_sums",
    "feature_expectations",
    "project_to_ball",
    "mmp_objective",
    "minimise_mmp",
    "mmp_objective_blocks",
    "minimise_mmp_blocks",
    "mmp_objective_policies",
    "structured_loss",
    "MaxMarginStep",
]


def discounted_suffix_sums(f: np.ndarray, gamma: float) -> np.ndarray:
    """Per-pair discounted feature sums along one trajectory (Monte-Carlo estimate of eq. 3).

    f: (T, D) features f(s_t, a_t) of one trajectory in time order (any trailing
    shape works; the sum runs over axis 0). Returns float64 of the same shape
    with row t = sum_{k >= t} gamma^(k - t) f_k, i.e. mu_hat(s_t, a_t); row 0 is
    the trajectory's whole discounted sum f^tau. T = 0 gives an empty array.
    """
    f = np.asarray(f, dtype=np.float64)
    out = np.empty_like(f)
    acc = np.zeros(f.shape[1:], dtype=np.float64)
    # eq. 3 along the sampled trajectory: mu(s_t, a_t) = f_t + gamma mu(s_{t+1}, a_{t+1})
    for t in range(f.shape[0] - 1, -1, -1):
        acc = f[t] + gamma * acc
        out[t] = acc
    return out


def feature_expectations(fs: Sequence[np.ndarray], gamma: float) -> np.ndarray:
    """Feature expectations mu of a set of trajectories (eq. 11).

    fs: N_T arrays of shape (L_i, D), the features f(s_t^i, a_t^i) of trajectory
    i in time order (L_i = 0 allowed: it contributes zeros). Returns (D,)
    float64: mu = (1/N_T) sum_i sum_{t=1}^{L_i} gamma^(t-1) f(s_t^i, a_t^i).
    """
    if len(fs) == 0:
        raise ValueError("feature_expectations needs at least one trajectory")
    total = None
    for f in fs:
        f = np.asarray(f, dtype=np.float64)
        # eq. 11 inner sum: sum_{t=1}^{L_i} gamma^(t-1) f(s_t, a_t)   (weight 1 on the first pair)
        weights = float(gamma) ** np.arange(f.shape[0], dtype=np.float64)
        s = np.tensordot(weights, f, axes=(0, 0))
        total = s if total is None else total + s
    # eq. 11 outer: (1 / N_T) sum_i
    return total / len(fs)


def project_to_ball(theta: np.ndarray, radius: float = 1.0) -> np.ndarray:
    """Euclidean projection onto {||theta||_2 <= radius} (the constraint of Algorithm 1, line 5).

    Returns a new float64 array: theta itself if inside, else theta * radius / ||theta||_2.
    """
    theta = np.array(theta, dtype=np.float64)
    norm = float(np.linalg.norm(theta))
    if norm > radius:
        theta *= radius / norm
    return theta


def mmp_objective(
    theta: np.ndarray, expert: np.ndarray, learner: np.ndarray, loss: np.ndarray, lam: float
) -> tuple[float, np.ndarray]:
    """The MMP objective (eq. 13) per state-action pair, with a subgradient.

    theta: (D,) reward weights; expert: (N, D) expert feature-expectation
    estimates mu_hat_E(s_n, a_n) at the N expert pairs; learner: (N, A, D) the
    learner's estimates mu_hat_pi(s_n, a) for every action a in the expert's
    state s_n; loss: (N, A) margin loss l(s_n, a) >= 0 (paper: 0 for the
    expert's action, 1 otherwise); lam: lambda_1 >= 0.

    J(theta) = (1/N) sum_n [ max_a (theta . learner[n, a] + loss[n, a]) - theta . expert[n] ]
               + lam / 2 ||theta||^2,
    returned with the subgradient (1/N) sum_n (learner[n, a*_n] - expert[n]) + lam theta,
    a*_n the maximiser (lowest index on ties). Q-values are theta^T mu (eq. 3).
    """
    theta = np.asarray(theta, dtype=np.float64)
    expert = np.asarray(expert, dtype=np.float64)
    learner = np.asarray(learner, dtype=np.float64)
    loss = np.asarray(loss, dtype=np.float64)
    n = expert.shape[0]
    if n == 0:
        raise ValueError("mmp_objective needs at least one expert pair")
    # eq. 3: Q^pi(s, a) = theta^T mu^pi(s, a), plus the margin loss l(s, a)
    scores = learner @ theta + loss  # (N, A)
    a_star = np.argmax(scores, axis=1)  # lowest index on ties
    rows = np.arange(n)
    q_expert = expert @ theta  # Q_theta^{pi_E}(s_n, a_n)
    # eq. 13: J = sum_n [max_pi (Q^pi(s_n, a_n) + l) - Q_theta^{pi_E}(s_n, a_n)] + lambda_1/2 ||theta||^2
    # (averaged over the N pairs instead of summed, so lam and the step size do not scale with N)
    value = float(np.mean(scores[rows, a_star] - q_expert) + 0.5 * lam * (theta @ theta))
    # subgradient: dJ/dtheta = (1/N) sum_n (mu_pi(s_n, a*_n) - mu_E(s_n, a_n)) + lambda_1 theta
    grad = (learner[rows, a_star] - expert).mean(axis=0) + lam * theta
    return value, grad


def mmp_objective_blocks(
    theta: np.ndarray, blocks: np.ndarray, offset: np.ndarray, loss: np.ndarray, lam: float
) -> tuple[float, np.ndarray]:
    """:func:`mmp_objective` when the learner's side is f(s_n, a) + gamma mu(next_n), f one-hot by action.

    f(s, a) puts the state's block b(s) (B values) into action a's slot of D = A * B,
    so theta^T f(s_n, a) = b(s_n) . theta_a with theta_a = theta[a B : (a + 1) B]:
    A dot products of length B instead of one of length D per action.

    blocks: (N, B) the blocks b(s_n); offset: (N, D) gamma mu(next_n) - expert[n]
    (the part that is the same for every action); loss: (N, A); lam: lambda_1.
    Equal to ``mmp_objective(theta, expert, learner, loss, lam)`` with
    ``learner[n, a] = f(s_n, a) + gamma mu(next_n)`` (a test checks it).
    """
    return _greedy_blocks_objective(theta, blocks, offset, offset.mean(axis=0), loss, lam)


def _greedy_blocks_objective(
    theta: np.ndarray,
    blocks: np.ndarray,
    offset: np.ndarray,
    offset_mean: np.ndarray,
    loss: np.ndarray,
    lam: float,
) -> tuple[float, np.ndarray]:
    """:func:`mmp_objective_blocks` with the offset's mean over the pairs given (it does not change
    while theta does)."""  # fmt: skip
    values = _action_values(theta, blocks, loss)
    chosen = np.zeros_like(values)
    chosen[np.arange(len(values)), np.argmax(values, axis=1)] = 1.0  # lowest index on ties
    return _blocks_objective(theta, blocks, offset, offset_mean, values, chosen, lam)


def mmp_objective_policies(
    theta: np.ndarray,
    blocks: np.ndarray,
    offset: np.ndarray,
    loss: np.ndarray,
    policies: np.ndarray,
    lam: float,
) -> tuple[float, np.ndarray]:
    """:func:`mmp_objective_blocks` with eq. 13's max over the learner's policies instead of actions.

    policies: (J, N, A), pi_j(a | s_n) of the J policies the learner has produced, in the
    demonstrated states. In each state s_n the alternative to the expert's pair is the policy j
    whose expected loss-augmented value sum_a pi_j(a | s_n) (theta^T f(s_n, a) + l(s_n, a)) is
    highest (lowest j on ties). With one-hot rows for every action this is
    :func:`mmp_objective_blocks` (a test checks it); with the learner's Boltzmann policies, a
    state where every policy so far takes the expert's action costs nothing. The policies enter by
    their action probabilities in the expert's states, not by their rollouts: what follows each
    alternative is in ``offset`` (the expert's continuation by default, which cancels).
    """
    return _per_state_policies_objective(
        theta, blocks, offset, offset.mean(axis=0), loss, _per_state(policies), lam
    )


def _per_state(policies: np.ndarray) -> np.ndarray:
    """policies (J, N, A) as (N, J, A), contiguous: each state's J rows side by side."""
    return np.ascontiguousarray(np.asarray(policies, dtype=np.float64).transpose(1, 0, 2))


def _per_state_policies_objective(
    theta: np.ndarray,
    blocks: np.ndarray,
    offset: np.ndarray,
    offset_mean: np.ndarray,
    loss: np.ndarray,
    per_state: np.ndarray,
    lam: float,
) -> tuple[float, np.ndarray]:
    """:func:`mmp_objective_policies` on policies laid out (N, J, A) (:func:`_per_state`), with the
    offset's mean over the pairs given.

    The same sums over a as in the (J, N, A) layout, bit for bit (a test checks it); the max
    over j then runs along memory, which takes about 40 % off an update.
    """
    values = _action_values(theta, blocks, loss)
    scores = np.einsum("nja,na->nj", per_state, values)
    rows = np.arange(len(values))
    chosen = per_state[rows, np.argmax(scores, axis=1)]  # (N, A), lowest j on ties
    return _blocks_objective(theta, blocks, offset, offset_mean, values, chosen, lam)


def _action_values(theta: np.ndarray, blocks: np.ndarray, loss: np.ndarray) -> np.ndarray:
    """theta^T f(s_n, a) + l(s_n, a), (N, A), from the state blocks (N, B)."""
    per_action = np.asarray(theta, dtype=np.float64).reshape(-1, blocks.shape[1])  # (A, B)
    return blocks @ per_action.T + loss


def _blocks_objective(
    theta: np.ndarray,
    blocks: np.ndarray,
    offset: np.ndarray,
    offset_mean: np.ndarray,
    values: np.ndarray,
    chosen: np.ndarray,
    lam: float,
) -> tuple[float, np.ndarray]:
    """J and its subgradient when state n's alternative weighs its actions by chosen[n] (N, A);
    ``offset_mean`` is ``offset.mean(axis=0)``, computed once per minimisation by its callers."""
    theta = np.asarray(theta, dtype=np.float64)
    n = len(values)
    value = float(np.mean((chosen * values).sum(axis=1) + offset @ theta) + 0.5 * lam * (theta @ theta))
    # subgradient: (1/N) sum_n sum_a chosen[n, a] f(s_n, a) + mean(offset) + lambda_1 theta
    grad = (chosen.T @ blocks).reshape(-1) / n + offset_mean + lam * theta
    return value, grad


def projected_subgradient(
    objective: Callable[[np.ndarray], tuple[float, np.ndarray]],
    theta0: np.ndarray,
    steps: int,
    step_size: float,
    decay: float,
    normalise: bool = False,
) -> tuple[np.ndarray, float]:
    """Minimises ``objective(theta) -> (J, subgradient)`` s.t. ||theta||_2 <= 1, the one loop of
    NIRL's max margin (eq. 13) and SCIRL's step 3.

    theta_{k+1} = P(theta_k - sigma_k d_k), sigma_k = step_size / (1 + decay k), k = 0..steps-1,
    P :func:`project_to_ball`; d_k the subgradient, or with ``normalise`` the subgradient over its
    norm (a zero subgradient then stops: every margin is met). theta0 is projected first. Returns
    the iterate with the lowest J seen, the first and last included (earliest on ties), and that J.
    """
    theta = project_to_ball(theta0)
    best_theta, best_value = theta.copy(), np.inf
    for k in range(int(steps) + 1):
        value, grad = objective(theta)
        if value < best_value:
            best_theta, best_value = theta.copy(), value
        norm = float(np.linalg.norm(grad)) if normalise else 1.0
        if k == steps or norm == 0.0:
            break
        sigma = step_size / (1.0 + decay * k)
        # theta <- theta - sigma_1 dJ/dtheta (section IV-B), then back into the ball ||theta||_2 <= 1
        theta = project_to_ball(theta - sigma * grad / norm)
    return best_theta, float(best_value)


def minimise_mmp(
    theta0: np.ndarray,
    expert: np.ndarray,
    learner: np.ndarray,
    loss: np.ndarray,
    lam: float,
    steps: int,
    step_size: float,
    decay: float = 0.0,
) -> tuple[np.ndarray, float]:
    """Projected subgradient descent on eq. 13 s.t. ||theta||_2 <= 1 (Algorithm 1, line 5).

    theta <- P(theta - sigma_k g_k), sigma_k = step_size / (1 + decay k), k = 0..steps-1,
    with P :func:`project_to_ball` (radius 1) and g_k from :func:`mmp_objective`
    (paper: sigma_1 in [0, 1]). theta0 is projected first (unchanged if feasible).
    Returns the iterate with the lowest J seen, theta0's projection and the final
    iterate included (earliest on ties), and that J: the margin t^(i).
    """
    return projected_subgradient(
        lambda theta: mmp_objective(theta, expert, learner, loss, lam), theta0, steps, step_size, decay
    )


def minimise_mmp_blocks(
    theta0: np.ndarray,
    blocks: np.ndarray,
    offset: np.ndarray,
    loss: np.ndarray,
    lam: float,
    steps: int,
    step_size: float,
    decay: float = 0.0,
    policies: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """:func:`minimise_mmp` with the objective of :func:`mmp_objective_blocks` (same iterates), or of
    :func:`mmp_objective_policies` when ``policies`` (J, N, A) is given."""
    mean = offset.mean(axis=0)  # the same at every step: computed once
    per_state = None if policies is None else _per_state(policies)

    def objective(theta: np.ndarray) -> tuple[float, np.ndarray]:
        if per_state is None:
            return _greedy_blocks_objective(theta, blocks, offset, mean, loss, lam)
        return _per_state_policies_objective(theta, blocks, offset, mean, loss, per_state, lam)

    return projected_subgradient(objective, theta0, steps, step_size, decay)


def structured_loss(expert_actions: np.ndarray, loss: float) -> np.ndarray:
    """l(s, a) of the structured hinge, (N, 6): 0 for the expert's action, ``loss`` for the others."""
    table = np.full((len(expert_actions), N_ACTIONS), float(loss))
    table[np.arange(len(table)), expert_actions.astype(int)] = 0.0
    return table


class MaxMarginStep:
    """NIRL's reward step (Algorithm 1, line 5): theta by projected subgradient on eq. 13.

    ``loop`` and ``own`` are the loop's config and this step's (``nirl_mj.learn.config``);
    ``matching`` chooses
    what the margin compares ("paper": eq. 11 expectations of whole trajectories;
    "occupancy": per-pair discounted sums with ``future_mix`` choosing what follows
    a deviation, every action an alternative; "policy": as "occupancy", but the
    alternatives in each demonstrated state are the learner's policies so far,
    :func:`mmp_objective_policies`), ``margin_loss`` the loss l, ``mmp_*`` the optimiser.
    """

    def __init__(self, loop: LoopConfig, own: MaxMarginConfig, demos: Sequence) -> None:
        from nirl_mj.data.trajectory import stack_pairs
        from nirl_mj.learn.reward import pair_features, state_reward_features

        self.loop, self.own = loop, own
        self.demo_phi, self.demo_actions = stack_pairs(demos)
        fs = trajectory_pair_features(demos, self.loop.reward_features)
        # "policy" matching: pi_j(. | s_n) of every policy that drove the rollouts so far, (N, 6) each
        self.policies: list[np.ndarray] = []
        if self.own.matching == "paper":
            self.expert_mu = feature_expectations(fs, self.loop.gamma)  # eq. 11, (D,)
            return
        self.expert = np.concatenate([discounted_suffix_sums(f, self.loop.gamma) for f in fs])
        # mu_E(s_{t+1}, a_{t+1}) along the demonstration (zero after its last pair), (N, D)
        demonstrated = pair_features(self.demo_phi, self.demo_actions, self.loop.reward_features)
        self.expert_next = (self.expert - demonstrated) / self.loop.gamma
        self.blocks = state_reward_features(self.demo_phi, self.loop.reward_features)  # (N, B)
        self.loss = structured_loss(self.demo_actions, self.loop.margin_loss)  # (N, 6), fixed

    def learner_future(self, trajectories: Sequence) -> np.ndarray:
        """What follows each demonstrated pair on the learner's side, mu(next), (N, D), under the
        per-pair readings: the learner's own mean discounted sum (``future_mix`` = 1), the expert's
        continuation (0, akin to SCIRL's heuristic, see docs/ALGORITHM.md), or a mixture."""
        future = (1.0 - self.own.future_mix) * self.expert_next
        if self.own.future_mix:
            fs = trajectory_pair_features(trajectories, self.loop.reward_features, skip_empty=True)
            mean_sum = np.concatenate([discounted_suffix_sums(f, self.loop.gamma) for f in fs]).mean(axis=0)
            future = future + self.own.future_mix * mean_sum
        return future

    def paper_margin_loss(self, greedy_on_demos: np.ndarray) -> float:
        """The paper reading's loss, averaged over the demonstrated pairs: l where the learned policy
        does not reproduce the expert's pair, else 0."""
        return float(np.mean(np.where(greedy_on_demos == self.demo_actions, 0.0, self.loop.margin_loss)))

    def update(
        self,
        theta: np.ndarray,
        trajectories: Sequence,
        iteration: int,
        greedy_on_demos: np.ndarray,
        context: object = None,
    ) -> tuple[np.ndarray, float]:
        """The next theta and the margin t (-min J: how far the best reward still puts the
        expert above every loss-augmented alternative; under the per-state occupancy reading the
        expert's own action is an alternative, so t <= 0 there).
        ``context`` (the rollouts' policy) is read by the "policy" matching only."""
        lr = self.own.mmp_step_size / (1.0 + self.own.mmp_step_decay * iteration)
        lam, steps = self.own.mmp_lambda, self.own.mmp_steps
        if self.own.matching == "paper":
            # eq. 13 on eq. 11's expectations: every demonstrated pair has the same expert side
            # mu_E and the same alternative mu (the learner's whole trajectories) whatever the
            # action, so J = theta . (mu - mu_E) + mean l + lambda/2 ||theta||^2: one pair, one action
            fs = trajectory_pair_features(trajectories, self.loop.reward_features, skip_empty=True)
            mu = feature_expectations(fs, self.loop.gamma)  # eq. 11 for the learner
            loss = np.array([[self.paper_margin_loss(greedy_on_demos)]])
            theta, j_min = minimise_mmp(theta, self.expert_mu[None], mu[None, None], loss, lam, steps, lr)
            return theta, -j_min
        policies = None
        if self.own.matching == "policy":
            if context is None:
                raise ValueError("NIRL's policy matching needs the rollouts' policy (RolloutContext)")
            self.policies.append(context.action_probabilities(self.demo_phi))
            policies = np.stack(self.policies)
        offset = self.loop.gamma * self.learner_future(trajectories) - self.expert
        theta, j_min = minimise_mmp_blocks(
            theta, self.blocks, offset, self.loss, lam, steps, lr, policies=policies
        )  # fmt: skip
        return theta, -j_min

    def state(self) -> dict[str, np.ndarray]:
        if not self.policies:
            return {}
        return {"policies": np.stack(self.policies)}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        self.policies = list(np.asarray(state["policies"], dtype=np.float64)) if "policies" in state else []
