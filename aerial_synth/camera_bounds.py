"""The camera bounds: one home for every command that renders (``render``, ``export``) and for
:class:`aerial_synth.camera.CameraConfig`, which enforces them. No imports, so the CLI modules
read them without slowing ``aerial-synth --help``."""

__all__ = ["MAX_IMAGE_PX", "MAX_ALTITUDE_M", "MAX_GSD_M", "MAX_FOCAL_PX"]

#: Largest image side, pixels.
MAX_IMAGE_PX = 16384
#: Above 100 km, 1 km per pixel or a 1e7 px focal length, a frame shows no vehicle at all
#: (an altitude of 1e30 m exported "vehicles 0" with a focal length of 8.3e30 px).
MAX_ALTITUDE_M = 100_000.0
MAX_GSD_M = 1000.0
MAX_FOCAL_PX = 1e7
