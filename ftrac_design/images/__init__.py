"""Image-level corrections and conversions that sit before segmentation."""
