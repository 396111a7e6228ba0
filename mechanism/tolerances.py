"""Every numerical tolerance of the library, in one place, each with its unit and its reason.

Modules import the names they use from here (as trimesh keeps its ``constants.tol``); a
tolerance changed here changes everywhere it is used. Domain numbers (a machine's constants)
never live here: they are in the machine's description.
"""

from __future__ import annotations

import math

# -- kinematics: solving a closed linkage's pose (kinematics.pose) --
POSITION_TOLERANCE = 1e-10  # m or rad: far below any clearance or kinematic accuracy we report
# of the model's size: a CAD export's rounding leaves ~1e-9 of it
RELATIVE_POSITION_TOLERANCE = 1e-8
ZERO_SNAP_RAD = 1e-9  # a shaft zero this close to the assembly pose is the pose (solver precision)
# a joint revolves with the driver when its ratio keeps one sign beyond this
REVOLVING_RATIO_TOLERANCE = 1e-3

# -- clearance between part shapes over a cycle (inspection.clearance, inspection.shapes) --
ANGLE_TOLERANCE_RAD = 1e-5  # refinement of a minimum or of the largest overlap volume (0.0006 deg)
DEPTH_ANGLE_TOLERANCE_RAD = 1e-4  # the deepest point's angle (the depth is flat there)
BOUNDARY_TOLERANCE_RAD = math.radians(1e-4)  # the ends of an interference range
HULL_TOLERANCE_M = 1e-6  # MuJoCo's GJK tolerance: keeps the convex-hull distance a lower bound
MIN_DEPTH_SPACING_M = 1e-6  # surface samples closer than this add nothing to a penetration depth

# -- CAD exports: mass properties and mate inference (converters) --
INERTIA_RELATIVE_TOLERANCE = 1e-6  # exports print 6+ significant digits
# kg m^2: the smallest principal moment a moving body keeps (MuJoCo refuses 1e-15)
MIN_MOMENT = 1e-12
# the least mass lent to a massless moving body (MuJoCo refuses under 1e-15 kg)
MIN_LENT_MASS_KG = 1e-9
# relative singular value below which a joint's freedoms count as locked by loops
JOINT_RANK_TOLERANCE = 1e-6
# relative: exports print 6+ digits, genuine mate constraints give singular values >> this
MATE_RANK_TOLERANCE = 1e-4
# singular value (of unit rotations) below which a pivot direction counts as free
PIVOT_TOLERANCE = 1e-3

# -- identification: what a recording must carry, and what the model already knows (sysid) --
# of a baseline regressor column's norm that the other columns cannot explain;
MIN_INDEPENDENT_FRACTION = 0.03
#                                  below it the parameter is not determined (a variance inflation above ~1100)
MOVING_SPEED_RAD_S = 0.1  # a sample moving at least this fast shows the sign of its friction (10x the velocity noise)
MIN_MOVING_SAMPLES = 200  # fewer moving samples than this carry nothing of the drive's dynamics
# each direction holds this share of the moving samples: a constant offset torque
BOTH_WAYS_FRACTION = 0.05
#                            is then separable from Coulomb friction (one way only, they are the same torque)
# rms gravity torque over the recording, relative to the rms drive torque, that the
GRAVITY_SIGNIFICANT = 0.05
#                             lumped baseline must carry (below it, gravity is within the friction's uncertainty)
# 1-sigma, relative: a CAD export's masses and centres of mass (gravity is a prior)
CAD_GRAVITY_TOLERANCE = 0.10
# 1-sigma, relative: the CAD's angle-dependent inertia (moving parts' masses)
CAD_INERTIA_TOLERANCE = 0.25
# 1-sigma, in log: a described machine's total inertia (parts the CAD lacks, rotor)
CAD_MEAN_INERTIA_TOLERANCE = 0.5
# 1-sigma, in log: a DC motor's torque per volt (Kt / R) against its datasheet
MOTOR_DATASHEET_TOLERANCE = 0.05
#   (resistance and torque constant each within a few % at 20 C); fitted only where the data fixes the torque scale
# a prior's hard bounds lie this many of its sigmas from the described value
PRIOR_BOUND_SIGMAS = 3.0

# -- simulation of the lumped drive (dynamics.lumped) --
# a first-order lag filter started this many time constants before the samples it is read at
# has forgotten its start to e^-40 = 4e-18 of it, below a double's rounding of the filtered signal
LAG_MEMORY_TIME_CONSTANTS = 40.0
