"""The add-on on real assets: its steps end to end, Uplift's choices, the fit error's grades and the
neural preview's closures in Cycles (docs/addon.md; the preview against torch in docs/neural-material.md)."""
