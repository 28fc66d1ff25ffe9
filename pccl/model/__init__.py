"""The model: compiled program, configuration layout, transition system, options, reductions."""
