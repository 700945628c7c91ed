"""Check a student's ``so101_forward_kinematics.py`` against this package, factor by factor.

``so101-check-fk PATH`` (or ``python -m so101_kinematics.checker PATH``): the module is
imported in a separate, time-bounded process (:mod:`.sandbox`, :mod:`.probe`), its
factors and its FK are compared with this package (:mod:`.fk_compare`), known mistakes are
named (:mod:`.diagnose`), and the result is written for the student, as JSON, as
Gradescope's ``results.json`` or as one CSV row per student (:mod:`.report`).

``so101-check-ik PATH`` (or ``python -m so101_kinematics.checker.ik PATH``) is its
sibling for a student's ``so101_inverse_kinematics.py``: the same sandbox, FK(IK(p))
at reachable targets with this package's FK (:mod:`.ik`, :mod:`.ik_targets`,
:mod:`.ik_compare`).

``so101-check-traj PATH`` (or ``python -m so101_kinematics.checker.traj PATH``) runs a
student's ``move_to_pose_cubic`` (assignment 9) in the same sandbox against a recording
stand-in for MuJoCo and names what differs from the course's cubic (:mod:`.traj`,
:mod:`.traj_probe`, :mod:`.traj_compare`).
"""

__all__: list[str] = []
