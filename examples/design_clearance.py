"""Needle-to-hook clearance of the shipped machine over one arm revolution."""

import mechanism

result = mechanism.clearance(None, "needle:hook,needle:needle_plate")
for pair in result.results:
    print(f"{pair.pair.label}: {pair.min_distance_mm:.3f} mm at {pair.angle_deg:.1f} deg")
