"""The compensators: scikit-learn estimators predicting the internal wrench (or joint torques)
from ``[q, q̇, q̈]``, the registry of those ftdrake ships, how ``train`` builds them, and their
hyper-parameter tuning."""
