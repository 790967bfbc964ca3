"""Paper I (Lee et al. 2021): event-based FSM walking with an operational-space WBC."""
