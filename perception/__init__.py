"""Perception: camera frames (RGB-D and intrinsics) turned into part detections, and detections into tracks that
ride the conveyor. A pure library: no I/O, no physics, no bus; it sees only what a camera gives (never the sim's
segmentation or poses)."""
