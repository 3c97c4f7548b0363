"""Motion planning: OMPL adapter, grasps, object-space to robot-space plans (Algorithm 2)."""
