"""mechanism.files."""
