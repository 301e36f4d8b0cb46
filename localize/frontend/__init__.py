"""The localizer's front end: a camera frame -> its labels -> its edge image."""
