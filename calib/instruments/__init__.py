"""Static instruments and their tests: north-finding by gyrocompassing (:mod:`.northfind`, planned by
:mod:`.northfind_plan`), the tilt-sensor static test (:mod:`.tilt`), and the holds both are made of
(:mod:`.holds`)."""
