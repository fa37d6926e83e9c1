"""Device profiles: CiA 402 drives, CiA 401 generic I/O."""
