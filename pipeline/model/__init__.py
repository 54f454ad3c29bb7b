"""What a whisker and an array are, engine-neutral: morphology, geometry, joints, follicle,
damping, extensions, loads, kinematics, rotations and what a trial outputs (SI units). Imports no
engine and no scene (docs/architecture.md)."""
