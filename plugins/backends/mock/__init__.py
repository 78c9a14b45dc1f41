"""``mock``: the offline default pilot -- a simulated LLM, not a canned script.

It decides only from what the prompt carries: it decodes the camera PNG and the LiDAR picture
(or parses the text modalities), reads the human instruction, notices whether the system
prompt has the security prefix and whether the reference state R_{i-1} is present, and reads
the refusal reasons fed back on a retry. It never sees the simulator's state. It answers in
the JSON schema a real LLM is asked for. Its weaknesses are the options below -- seeded by the
rng each call receives, documented in ``docs/backends.md``. The defaults were calibrated
(``docs/evidence/backends.md``) so the baseline arm lands near the paper's GPT-4o baseline;
numbers it produces simulate an LLM, they do not measure one.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy

from .options import MockOptions


@hookimpl
def register_llm_backends(register):
    register("mock", lazy(f"{__name__}.backend", "MockPilot"), options=MockOptions,
             description="offline simulated pilot: reads the prompt's images/text, seeded weaknesses")
