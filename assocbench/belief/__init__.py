"""The open-loop belief every track shares: difficulty knobs (``config``) and the sampled planar
estimate (``planar``)."""
