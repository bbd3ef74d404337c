"""The learner, a library on its own: input type, backbones, C2INet, continual methods, metrics."""
