"""The method: segmentation of demos into macro actions, plain sequences, the FAVAE, its traversal and the metrics
against the experts' ground truth. Plain computations over artifacts; no CLI, no RL."""
