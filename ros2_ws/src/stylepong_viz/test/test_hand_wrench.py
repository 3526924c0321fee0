"""The hand's wrench for display: the paddle's load from the URDF as drag_teach reads it, its weight removed."""

import numpy as np
import pytest

from stylepong_description import robot_model as rm
from stylepong_description.robot_state import RobotState
from stylepong_viz.batch_transforms import LinkPoses
from stylepong_viz.hand_wrench import hand_wrench_in_tool, tool_load_from_urdf

GRAVITY_BASE = np.array([0.0, 0.0, -9.81])


def test_the_tool_load_is_drag_teachs():
    pytest.importorskip('pinocchio')
    from stylepong_fdcc.wrench_conditioning import tool_load_from_model

    ours = tool_load_from_urdf(rm.urdf_xml_for_display(), rm.TOOL_FRAME)
    theirs = tool_load_from_model(rm.pinocchio_model())
    assert ours.mass_kg == pytest.approx(theirs.mass_kg, rel=1e-9)
    assert np.allclose(ours.com_m, theirs.com_m, atol=1e-9)


def test_a_urdf_without_a_tool_load_is_refused():
    with pytest.raises(ValueError, match='tool0'):
        tool_load_from_urdf('<robot name="r"><link name="tool0"/></robot>', 'tool0')


@pytest.mark.parametrize('q', [np.zeros(6), np.array([0.3, -1.2, 1.4, -1.8, -1.57, 0.7])])
def test_the_hand_wrench_is_the_reading_less_the_paddle_weight_as_drag_teach_removes_it(q):
    pytest.importorskip('pinocchio')
    from stylepong_fdcc.wrench_conditioning import gravity_wrench_on_tool, tool_load_from_model

    model = rm.pinocchio_model()
    import pinocchio as pin

    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    rotation = data.oMf[model.getFrameId(rm.TOOL_FRAME)].rotation
    weight = gravity_wrench_on_tool(tool_load_from_model(model), rotation, GRAVITY_BASE)
    hand = np.array([1.0, -2.0, 3.0, 0.1, 0.2, -0.3])
    _, tool_rotation = LinkPoses(RobotState(rm.urdf_xml_for_display()), rm.TOOL_FRAME).poses(q)
    ours = hand_wrench_in_tool(
        weight + hand, tool_load_from_urdf(rm.urdf_xml_for_display(), rm.TOOL_FRAME), tool_rotation[0], GRAVITY_BASE
    )
    assert np.allclose(ours, hand, atol=1e-9)
