"""
The RViz config and the angular momentum arrow: what RViz is told to show is what is sent.

RViz itself cannot run here (no rviz2 wheel, no display): the config is checked as RViz
reads it (YAML, its display classes and their topic properties) against what the node and
the arrow helper publish; the arrow's markers are checked as RViz draws them (an ARROW
given by two points, a label at its tip).
"""

import math
from pathlib import Path

from geometry_msgs.msg import Vector3Stamped
from rigid_body_sim.node.help_text import help_text
from rigid_body_sim.node.momentum_arrow import arrow_markers
from rigid_body_sim.node.momentum_arrow import label
from rigid_body_sim.node.parameters import PARAMETERS
from visualization_msgs.msg import Marker
import yaml

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / 'rviz' / 'rigid_body_sim.rviz'
# The display classes the issue asks for, with the topic each must show (None: TF, no topic).
REQUIRED = {
    'rviz_default_plugins/TF': None,
    'rviz_default_plugins/Marker': 'marker',
    'rviz_default_plugins/Odometry': 'odom',
    'rviz_default_plugins/MarkerArray': 'angular_momentum_arrow',
}
# rviz_default_plugins' display classes (plugins_description.xml of ros2/rviz, jazzy) that
# this config may use.
KNOWN_CLASSES = set(REQUIRED) | {'rviz_default_plugins/Grid', 'rviz_default_plugins/Axes'}


def _config():
    return yaml.safe_load(CONFIG.read_text())


def _displays():
    return _config()['Visualization Manager']['Displays']


def test_the_rviz_config_shows_tf_the_body_odometry_and_the_momentum_arrow():
    displays = _displays()
    by_class = {display['Class']: display for display in displays}
    assert set(by_class) <= KNOWN_CLASSES, set(by_class) - KNOWN_CLASSES
    for display_class, topic in REQUIRED.items():
        display = by_class.get(display_class)
        assert display is not None, f'no {display_class} display'
        assert display['Enabled'] is True and display['Value'] is True, display_class
        if topic is not None:
            assert display['Topic']['Value'] == topic, (display_class, display['Topic'])
    # Each display says what it shows; the arrow's name says what L is and its unit.
    names = [display['Name'] for display in displays]
    assert len(set(names)) == len(names)
    assert 'N m s' in by_class['rviz_default_plugins/MarkerArray']['Name']


def test_the_rviz_topics_are_relative_and_published_by_the_node_or_the_arrow_helper():
    # Relative names: an RViz started in the node's namespace (sim.launch.py) shows it.
    published = set()
    for line in help_text(width=100).splitlines():
        words = line.split()
        if line.startswith('  ') and not line.startswith('   ') and len(words) > 1 \
                and '/' in words[1]:
            published.add(words[0])
    assert {'pose', 'marker', 'odom', 'angular_momentum'} <= published, published
    for display in _displays():
        if 'Topic' not in display:
            continue
        topic = display['Topic']['Value']
        assert not topic.startswith('/'), topic
        assert topic in published | {'angular_momentum_arrow'}, topic
        # The node's state QoS is reliable and volatile: a subscription asking for more
        # (transient local) would never match.
        assert display['Topic']['Reliability Policy'] in ('Reliable', 'Best Effort')
        assert display['Topic']['Durability Policy'] == 'Volatile'


def test_the_rviz_fixed_frame_is_the_node_s_default_world_frame():
    world_frame = next(spec.default for spec in PARAMETERS if spec.name == 'world_frame')
    assert _config()['Visualization Manager']['Global Options']['Fixed Frame'] == world_frame


def _momentum(x, y, z, frame='world'):
    message = Vector3Stamped()
    message.header.frame_id = frame
    message.header.stamp.sec = 7
    message.vector.x, message.vector.y, message.vector.z = x, y, z
    return message


def test_the_arrow_runs_from_the_centre_of_mass_along_l_scaled():
    markers = arrow_markers(_momentum(0.0, 3.0, 4.0), (1.0, 2.0, -1.0), 0.5).markers
    arrow, text = markers
    assert arrow.type == Marker.ARROW and arrow.action == Marker.ADD
    assert arrow.header.frame_id == 'world' and arrow.header.stamp.sec == 7
    tail, tip = arrow.points
    assert (tail.x, tail.y, tail.z) == (1.0, 2.0, -1.0)
    assert (tip.x, tip.y, tip.z) == (1.0, 3.5, 1.0)  # tail + 0.5 m per N m s x L
    assert arrow.id != text.id and arrow.ns == text.ns
    # The head is drawn in proportion to the 2.5 m arrow, never thicker than it is long.
    assert 0.0 < arrow.scale.x < arrow.scale.y < 2.5
    assert text.type == Marker.TEXT_VIEW_FACING and text.text == label(5.0, 0.5)
    # The label sits beyond the tip, on the arrow's line.
    beyond = (text.pose.position.y - 2.0) / 1.5
    assert beyond > 1.0
    assert math.isclose(text.pose.position.z, -1.0 + beyond * 2.0)


def test_the_label_reads_as_an_angular_momentum_with_its_unit_and_scale():
    assert label(4.0, 1.0) == 'L = 4 N m s'
    assert label(0.0245, 10.0) == 'L = 0.0245 N m s (arrow 10 m per N m s)'


def test_a_zero_or_non_finite_momentum_deletes_the_arrow_and_its_label():
    for vector in ((0.0, 0.0, 0.0), (math.nan, 0.0, 1.0)):
        markers = arrow_markers(_momentum(*vector), (0.0, 0.0, 0.0), 1.0).markers
        assert [marker.action for marker in markers] == [Marker.DELETE, Marker.DELETE]
        assert [marker.id for marker in markers] == [0, 1]
