"""mechanism.physics."""
