"""The commented scene template written by ``shapedisplay new scene NAME``."""
from __future__ import annotations

TEMPLATE = '''\
# Tactile scene "{name}" for shapedisplay.
# Check it:    shapedisplay check {file}
# Compile it:  shapedisplay compile {file} -o {stem}.npz
# Every length, force and stiffness carries its unit ("12 mm", "0.5 N", "1 N/mm").
# Coordinates: x to the right, y along the rows; a widget's `position` is the
# corner of its box with the smallest x and y (or give `center`).

[scene]
name = "{name}"
description = "describe the screen here"

[canvas]
size = "100x60 mm"          # or: pixels = "1080x640" with dpi = 160; one length ("120 mm") = 1-D strip
resolution = "0.5 mm"       # sample spacing; identical widgets snapped to it are stored once

[device]
profile = "handheld-stick"  # bundled: handheld-stick, desktop-rig, linear-slider, ... or a path

[mapping]
n_base = "1 N"              # N1, force on flat ground (published 0.5 N); above the device
                            # minimum so dents and grooves (less force) can be felt
n_gain = "1 N/mm"           # extra normal force per mm of height
direction = "symmetric"     # "one-sided": uphill resists (bump), downhill releases (dent)
# slope_friction = 0.2      # K_mu per unit slope, with direction = "one-sided"

[defaults]                  # any widget key, for every widget that has it
overlap = "max"             # overlapping widgets: max | min | add | over (later wins)
levels = 5                  # perceived-height steps for `level = 1..levels`
level_force = "4 N"         # force step of the top level; lower levels follow the power law

[defaults.button]           # defaults for one widget type
ramp = "10 mm"              # edge span L: published studies used 10-30 mm
edge = "linear"             # linear (the published ramp), cosine, or tent (no plateau)

[[widget]]
id = "ok"
type = "button"             # raised rounded rectangle
position = "10,15 mm"
size = "30x30 mm"
level = 3                   # or height = "2 mm", force = "2.5 N", force_step = "2 N"
corner_radius = "4 mm"

[[widget]]
id = "cancel"
type = "dent"               # sunk well (needs n_base above the device minimum to be felt as less force)
position = "60,15 mm"
size = "30x30 mm"
depth = "0.4 mm"

[[widget]]
id = "volume"
type = "slider"
position = "10,50 mm"
size = "60x8 mm"
track = "groove"            # or "ridge"
value = 0.3                 # thumb position 0..1
height = "1.5 mm"           # thumb height above the track
detents = 5                 # a count (evenly spaced, none at the ends), a spacing "10 mm", or "off"

[[widget]]
id = "mute"
type = "toggle"             # both states are compiled; the table shows `state`
position = "78,48 mm"
size = "16x8 mm"
state = "off"

# [[widget]]
# type = "ridge"            # a raised line; "groove" sinks it
# from = "5,5 mm"
# to = "95,5 mm"
# width = "2 mm"
# height = "0.5 mm"

# [[widget]]
# type = "image"            # a height map stretched over the box
# file = "terrain.png"
# position = "0,0 mm"
# size = "100x60 mm"
# height = "0:2 mm"

# [[widget]]
# type = "data"             # a scalar field driving its own haptic dimension
# channel = "friction_scale"  # or "burst_gain"
# values = [[0, 1], [2, 3]]   # or file = "field.npy"
# position = "0,0 mm"
# size = "100x60 mm"
# range = "0.8:1.5"           # stimulus (multiplier) range; equal data steps feel equal (power law)
'''


def render_template(name: str, file: str) -> str:
    """The template for scene ``name`` saved as ``file``."""
    from pathlib import Path
    return TEMPLATE.format(name=name, file=file, stem=Path(file).stem)
