import numpy as np

from mrlib.representation.skeleton import (
    CONTACT_JOINTS,
    JOINT_NAMES,
    NUM_CONTACTS,
    PARENTS,
    children,
    graph_distances,
    neighbourhood,
)


def test_tree_is_topologically_ordered():
    assert PARENTS[0] == -1
    assert all(0 <= p < j for j, p in enumerate(PARENTS) if j > 0)
    assert len(JOINT_NAMES) == len(PARENTS) == 24


def test_children_and_distances():
    ch = children()
    assert sorted(ch[0]) == [1, 2, 3]
    assert sorted(ch[9]) == [12, 13, 14]
    d = graph_distances()
    assert (d == d.T).all() and (np.diag(d) == 0).all()
    assert d[JOINT_NAMES.index("left_wrist"), JOINT_NAMES.index("left_elbow")] == 1
    # left hand -> right hand: hand, wrist, elbow, shoulder, collar, spine3, collar, shoulder, elbow, wrist, hand
    assert d[22, 23] == 10


def test_neighbourhood_radius_two():
    m = neighbourhood(2)
    assert m[0, 4] and not m[0, 7]  # pelvis sees knees (2 hops), not ankles (3 hops)
    assert m.sum(1).min() >= 3


def test_contacts_attach_to_feet_and_ankles():
    assert len(CONTACT_JOINTS) == NUM_CONTACTS == 6
    assert {JOINT_NAMES[j] for j in CONTACT_JOINTS} == {
        "left_foot",
        "left_ankle",
        "right_foot",
        "right_ankle",
    }
