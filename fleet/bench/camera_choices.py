"""What `fleet bench cameras` offers to time (kept apart from the bench itself: the CLI's parser reads them without
importing the simulator)."""

SIZES = ((64, 64), (128, 128), (320, 240), (640, 480))  # width x height, px
IMAGES = {"rgb": ["rgb"], "rgbd": ["rgb", "depth"], "all": ["rgb", "depth", "segmentation"]}
