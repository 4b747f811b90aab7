"""Events in: event arrays, sequences, the lens model, event frames."""
