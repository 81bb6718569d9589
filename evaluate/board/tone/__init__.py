"""What a camera and its processing did to the photos: the tone the study locates on (``values``, ``fit``), the
photo model (``photo_model``: blur, noise, sharpening) and whether the locator's model holds (``locator_fit``)."""
