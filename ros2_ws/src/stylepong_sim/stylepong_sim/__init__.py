"""MuJoCo UR5 table-tennis cell standing in for the hardware, and what surrounds it.

World spec, referee, virtual teacher, batched training world.
"""

import os

# MuJoCo picks its GL back end when it is first imported, and every module here that imports it does so
# after this file: without a display its renderer (videos, figures) needs EGL. MUJOCO_GL set by the user
# (egl, osmesa, glfw) is left alone; so is a machine with a DISPLAY.
if 'MUJOCO_GL' not in os.environ and not os.environ.get('DISPLAY'):
    os.environ['MUJOCO_GL'] = 'egl'
