"""How far datagen's flights are from a perfect simulation (``realism``, core/imaging/realism.py's
settings): the AHRS's roll and pitch (``ahrs``), the clocks of the camera and the odometry
(``timing``), lens distortion, motion blur and a rolling shutter (``optics``), the map the
localizer reads (``map_error``) and the camera it is told (``calibration``). The image effects
of the camera (noise, exposure, JPEG, dropouts) are core/imaging/camera_effects.py, shared with
train.
"""
