"""Close the model loop (issue 5): residual → missing effect → refit → report before/after."""

from .loop import DEFAULT_DECLARED, CloseloopResult, Finding, run_closeloop

__all__ = ["run_closeloop", "CloseloopResult", "Finding", "DEFAULT_DECLARED"]
