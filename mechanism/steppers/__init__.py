"""mechanism.steppers."""
