"""The ``calib`` command line and what it writes: the parser (:mod:`.cli`), the commands one module per group
(:mod:`.commands`: session, noise, temperature, closeloop, mag, instruments, and ``calib lab``), the main job
(:mod:`.demo`), the session report (:mod:`.report`), the rerun recordings (:mod:`.rerun`,
:mod:`.rerun_temperature`), ``calib inspect`` (:mod:`.inspect`) and the output boundary (:mod:`.outputs`).

Thin: every command is a library call a user can make; nothing below this folder imports it.
"""
