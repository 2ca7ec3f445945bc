"""Universal neural material (paper sec. 4): networks, training data, training, fitting."""
