"""Policy search: PI^2-CMA, natural policy gradient and DAPG, rollouts (Chapter 5)."""
