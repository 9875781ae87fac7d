"""Inference: priors, likelihood, sampler controller and fits (PINTS-style separate pieces)."""
