"""The open-loop belief every track shares: its difficulty knobs (``config``) and the sampled
estimate of a robot in the plane with a map of points (``planar``)."""
