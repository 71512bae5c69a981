"""Close the model loop: residual → missing effect (a cause, not a proxy) → refit → report before/after."""

from calib.closeloop.candidates import CandidateFamily, Channel, register_family
from calib.closeloop.loop import DEFAULT_DECLARED, CloseloopResult, Finding, run_closeloop

__all__ = ["run_closeloop", "CloseloopResult", "Finding", "DEFAULT_DECLARED", "CandidateFamily", "Channel",
           "register_family"]
