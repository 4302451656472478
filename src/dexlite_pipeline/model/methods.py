"""The method labels of the sampled stores' rows (``method``): which way the CVAE made each grasp.

Apart from ``model.sampling`` so that the stages that only read these labels (post-optimization)
import no network code.
"""

SYNTHESIS = "cvae_raw"
EXPAND_LATENT = "cvae_expand_latent"
EXPAND_POINT = "cvae_expand_point"
RECONSTRUCTION = "cvae_recon"  # learning ladder, fit rung: encoder-mean reconstructions of the training grasps
PRIOR_ON_TRAINING = "cvae_prior_train"  # learning ladder, in-distribution rung: pure synthesis on training objects
SHIPPED_SYNTHESIS = "shipped_raw"  # pure synthesis by the shipped (pretrained) model on held-out objects it never trained on
