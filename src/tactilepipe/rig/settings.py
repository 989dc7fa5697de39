"""The rig's device settings the command line offers: the DIGIT's stream modes and the Arduino
firmware's baud rate. Plain data, so that building the command line's parser (which every stage
does) loads none of the rig's device code (OpenCV capture, pyserial)."""

# the DIGIT's stream modes: (width, height) as the sensor sends them, and frames per second
MODES = {"qvga60": (320, 240, 60), "qvga30": (320, 240, 30), "vga30": (640, 480, 30), "vga15": (640, 480, 15)}
BAUD = 115200                        # the firmware's serial rate (docs/rig.md)
