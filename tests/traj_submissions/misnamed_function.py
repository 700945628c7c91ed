# the function named after the page's typo
import mujoco

from so101_mujoco_utils import send_position_command


def move_to_pose_cubc(m, d, viewer, desired_position, duration):
    mujoco.mj_step(m, d)
