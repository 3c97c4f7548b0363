"""Learning: policy search (PI^2-CMA, natural policy gradient and DAPG, rollouts;
Chapter 5) and the epoch bookkeeping of supervised training (`fit_state`)."""
