"""Chapter 3: kinematic models from one depth image: ResNet-18 mixture density network,
training, prediction, baselines."""

from typing import Literal, get_args

Estimator = Literal["most-likely", "densest", "max-point"]
"""How a mixture becomes one label vector (kinematics/predict.py); torch-free, so configs
can name it without importing the network."""
ESTIMATORS: tuple[str, ...] = get_args(Estimator)
