"""``zarco shore web``: the operator's live map in a browser (see :mod:`.server`)."""
