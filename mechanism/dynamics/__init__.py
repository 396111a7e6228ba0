"""mechanism.dynamics."""
