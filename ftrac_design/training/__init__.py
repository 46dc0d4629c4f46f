"""Training the learned feature detector (:mod:`ftrac_design.detector`) on this package's own
simulator: scenes with exact truth (:mod:`.scenes`), the maps the network learns
(:mod:`.targets`), the data set (:mod:`.dataset`), the network (:mod:`.net`, PyTorch — the
``train`` extra) and the training run that writes the ONNX weights and their model card
(:mod:`.run`)."""
