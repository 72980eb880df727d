"""twolink: a MuJoCo testbed for Busoniu, De Schutter & Babuska (ICARCV 2006)."""
import os as _os

# Headless rendering through EGL (NVIDIA driver, or Mesa's software device without a GPU).
# Set before anything imports mujoco; a user's own MUJOCO_GL wins.
_os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.1.0"
