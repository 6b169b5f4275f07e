"""Files shipped with the application: icons, marker layouts, posture priors, the template hand, screenshots."""
