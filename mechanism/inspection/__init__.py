"""mechanism.inspection.steps."""
