"""The sampler configuration, :class:`SamplerConfig`, and its rules: defined in the base module
:mod:`bayesfric.samplerconfig` (it imports only :mod:`bayesfric.errors`, so the command line
checks ``fit``'s sampler options before JAX loads) and re-exported here, where the engine and
the study read it."""

from bayesfric.samplerconfig import (
    BACKENDS,
    CHUNK_STEPS,
    INITS,
    METRICS,
    RULES,
    Rule,
    SamplerConfig,
    default_of,
    described,
)

__all__ = ["SamplerConfig", "Rule", "RULES", "BACKENDS", "METRICS", "INITS", "CHUNK_STEPS", "default_of",
           "described"]
