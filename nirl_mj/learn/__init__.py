"""Learning pieces of NIRL (paper section III-B, III-C and IV), pure functions, no simulation.

- ``network``: the 16-10-6 sigmoid Q-network G (eq. 6-7), the Boltzmann policy
  (eq. 8), greedy selection (eq. 9) and the cross-entropy cost with L2 (eq. 15)
  and its gradient-descent step.
- ``mmp``: discounted feature sums, the expert's feature expectations (eq. 11)
  and the model-free maximum-margin-planning objective (eq. 13) minimised by
  projected subgradient descent with ||theta||_2 <= 1 (Algorithm 1, line 5).
- ``sarsa``: the value targets the network is fitted to: on-policy SARSA (eq. 14),
  and the n-step returns of the default variant.
"""
