"""The paper's direct MLP decoder, kept as the baseline the shipped hybrid is measured against.

Its networks, training phases (energy penalty, sampling decoder) and furnace repair live
here; the rest of the package reaches them only through its kind entry (``mlp.kind.KIND``).
"""
