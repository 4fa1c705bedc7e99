"""Virtual test campaign: vehicle manoeuvres -> damper strokes -> virtual rig -> measured force files."""
