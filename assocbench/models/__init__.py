"""Measurement models and pose algebra, shared by the tracks and the estimators: the pinhole
bundle (``pinhole``, ``camera``), range-bearing (``range_bearing``), planar poses (``se2``),
polar lines (``polar_line``) and the depth frame (``depth_frame``); ``synthetic`` draws
association problems from them without rendering."""
