"""mechanism.sysid."""
