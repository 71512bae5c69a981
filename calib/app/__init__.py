"""The ``calib`` command line and what it writes: the parser and commands (:mod:`.cli`), the main job
(:mod:`.demo`), the session report (:mod:`.report`), the rerun recordings (:mod:`.rerun`,
:mod:`.rerun_temperature`), ``calib inspect`` (:mod:`.inspect`) and the output boundary (:mod:`.outputs`).

Thin: every command is a library call a user can make; nothing below this folder imports it.
"""
