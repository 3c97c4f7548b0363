"""Chapter 3: kinematic models from one depth image: ResNet-18 mixture density network,
training, prediction, baselines."""
