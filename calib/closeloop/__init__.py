"""Close the model loop: residual → missing effect (a cause, not a proxy) → refit → report before/after."""

from .candidates import CandidateFamily, Channel, register_family
from .loop import DEFAULT_DECLARED, CloseloopResult, Finding, run_closeloop

__all__ = ["run_closeloop", "CloseloopResult", "Finding", "DEFAULT_DECLARED", "CandidateFamily", "Channel",
           "register_family"]
