"""mechanism.kinematics.pose."""
