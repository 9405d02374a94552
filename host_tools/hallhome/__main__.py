from hallhome.cli import main

main()
