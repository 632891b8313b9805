"""Keyframe motion editor in the browser (`toddlerbot motion edit`): the robot in 3D from the spec, joint sliders
grouped by limb, a keyframe list, playback in the MuJoCo simulator with the actuator model, balance (centre of
mass, support polygon), saving to the motion YAML of `toddlerbot.policies.motions`.

Modules, one job each: `keyframes` (the edited motion and its YAML text), `mirror` (left/right mirror map from
the model's joint axes), `balance` (kinematic pose on the floor, CoM, support polygon), `playback` (the motion run
in the simulator), `scene` (the robot drawn with viser), `app` (the page: controls wired to the above).
"""
