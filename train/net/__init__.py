"""The SegNet and its pooling."""
