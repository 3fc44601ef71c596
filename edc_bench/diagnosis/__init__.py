"""Diagnosis: valve populations, the batch path, the classifier and the verdict."""
