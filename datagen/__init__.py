"""datagen: labeled corridor renders and evaluation flights with Mitsuba 3."""
