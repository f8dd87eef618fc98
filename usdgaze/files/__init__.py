"""Files a command reads and writes: identity checks (:mod:`.identity`) and the one writer
(:mod:`.transaction`; the paths it works with in :mod:`.paths`)."""
