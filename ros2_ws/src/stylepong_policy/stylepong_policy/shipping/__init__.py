"""Shipping: a chosen run's actor and records into `models/`, and a learned style's network into the skill
library (`models/skills/`), both written into the checkout."""
