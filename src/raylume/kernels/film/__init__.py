"""Film and sampling: the camera array and its rays, the random numbers of each sample, and the
film that sums samples per pixel."""
