"""Words of the tool study that params.yaml may use and the code builds from: the ResNet depths
and the baselines. Plain data without imports, so that the workflow reads it cheaply; the
parameter models (core/parameters/tool.py) and the model code (tool/model/variants.py) both take
them from here, so they cannot disagree."""

# the ResNet regressor's depths: block kind and blocks per stage (tool/model/network.py builds them)
RESNET_DEPTHS: dict[int, tuple[str, list[int]]] = {
    18: ("basic", [2, 2, 2, 2]),
    34: ("basic", [3, 4, 6, 3]),
    50: ("bottleneck", [3, 4, 6, 3]),
    101: ("bottleneck", [3, 4, 23, 3]),
}

# the baselines the model report fits beside each variant (tool/model/evaluate.py)
BASELINES: tuple[str, ...] = ("mean_predictor", "tactile_rmse_linear", "rest_frame_rmse_linear",
                              "one_finger_rmse_linear")
