"""Import before mujoco: without a display, MuJoCo's renderer needs EGL, chosen when mujoco is first imported.

MUJOCO_GL set by the user (egl, osmesa, glfw) is left alone; so is a machine with a DISPLAY.
"""
import os

if 'MUJOCO_GL' not in os.environ and not os.environ.get('DISPLAY'):
    os.environ['MUJOCO_GL'] = 'egl'
