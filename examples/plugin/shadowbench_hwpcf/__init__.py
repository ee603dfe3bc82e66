"""An example third-party shadowbench technique: 2x2 hardware-compare PCF."""
