"""A ride's result: stored by one writer, read back typed, its series, notes, passes and one-page report."""
