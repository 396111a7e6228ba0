"""mechanism.machine.machine."""
