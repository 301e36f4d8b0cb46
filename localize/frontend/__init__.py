"""The localizer's front end: a camera frame -> its labels -> its edge image.

- ``front_end``: ``FrontEnd`` (a source and the ``edges`` config) and the ``EdgeFrame`` it makes.
- ``sources``: where a frame's labels come from (Canny, the SegNet, the truth, a function).
- ``segmenter``: the cnn mode's ONNX SegNet and its prior-corrected labels.
- ``extractor``: a frame's edge image in each edge mode.
- ``boundaries``: class boundaries of a label map, snapped onto the image's edges.
- ``canny``: mode none's Canny edges and Hough segments.
- ``edge_image``: ``EdgeImage`` and the class-pair codes of its boundaries.
"""
