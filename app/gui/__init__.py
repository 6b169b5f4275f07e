"""The Qt desktop application: main window, controllers, dialogs and the Qt-free application object."""
