"""The model loop for the magnetometer: its candidate terms (:mod:`.terms`), the reference field
(:mod:`.reference`), the fit (:mod:`.fit`), identification and selection (:mod:`.identify`,
:mod:`.select`), metrics (:mod:`.metrics`) and the loop itself (:mod:`.loop`)."""
