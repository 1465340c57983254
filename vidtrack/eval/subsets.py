"""The benchmarks' published sequence lists, as small data tables (``vidtrack eval --subset NAME``).

OTB-2013 (Wu, Lim, Yang, "Online Object Tracking: A Benchmark", CVPR 2013: 51
sequences in 50 folders), OTB-50 (TB-50: 50 sequences in 49 folders) and
OTB-100 (TB-100 = OTB-2015: 100 sequences in 98 folders) of "Object Tracking
Benchmark" (TPAMI 2015); a folder with two targets (Jogging, Skating2) counts
as its two sequences.  The LaSOT test protocol (Fan et al., CVPR 2019): four
sequences of each of the 70 classes, 280 in all.
"""

from __future__ import annotations

OTB2013_FOLDERS = """
    Basketball Bolt Boy Car4 CarDark CarScale Coke Couple Crossing David David2 David3 Deer Dog1 Doll Dudek
    FaceOcc1 FaceOcc2 Fish FleetFace Football Football1 Freeman1 Freeman3 Freeman4 Girl Ironman Jogging Jumping
    Lemming Liquor Matrix Mhyang MotorRolling MountainBike Shaking Singer1 Singer2 Skating1 Skiing Soccer Subway
    Suv Sylvester Tiger1 Tiger2 Trellis Walking Walking2 Woman
""".split()

OTB50_FOLDERS = """
    Basketball Biker Bird1 BlurBody BlurCar2 BlurFace BlurOwl Bolt Box Car1 Car4 CarDark CarScale ClifBar Couple
    Crowds David Deer Diving DragonBaby Dudek Football Freeman4 Girl Human3 Human4 Human6 Human9 Ironman Jump
    Jumping Liquor Matrix MotorRolling Panda RedTeam Shaking Singer2 Skating1 Skating2 Skiing Soccer Surfer
    Sylvester Tiger2 Trellis Walking Walking2 Woman
""".split()

OTB100_FOLDERS = """
    Bird2 BlurCar1 BlurCar3 BlurCar4 Board Bolt2 Boy Car2 Car24 Coke Coupon Crossing Dancer Dancer2 David2 David3
    Dog Dog1 Doll FaceOcc1 FaceOcc2 Fish FleetFace Football1 Freeman1 Freeman3 Girl2 Gym Human2 Human5 Human7
    Human8 Jogging KiteSurf Lemming Man Mhyang MountainBike Rubik Singer1 Skater Skater2 Subway Suv Tiger1 Toy
    Trans Twinnings Vase
""".split() + OTB50_FOLDERS

#: LaSOT's test sequences: class, then the four sequence numbers.
_LASOT_TEST = """
    airplane 1 9 13 15
    basketball 1 6 7 11
    bear 2 4 6 17
    bicycle 2 7 9 18
    bird 2 3 15 17
    boat 3 4 12 17
    book 3 10 11 19
    bottle 1 12 14 18
    bus 2 5 17 19
    car 2 6 9 17
    cat 1 3 18 20
    cattle 2 7 12 13
    spider 14 16 18 20
    coin 3 6 7 18
    crab 3 6 12 18
    surfboard 12 4 5 8
    cup 1 4 7 17
    deer 4 8 10 14
    dog 1 7 15 19
    guitar 3 8 10 16
    person 1 5 10 12
    pig 2 10 13 18
    rubicCube 1 6 14 19
    swing 10 14 17 20
    drone 13 15 2 7
    pool 12 15 3 7
    rabbit 10 13 17 19
    racing 10 15 16 20
    robot 1 19 5 8
    sepia 13 16 6 8
    sheep 3 5 7 9
    skateboard 16 19 3 8
    tank 14 16 6 9
    tiger 12 18 4 6
    train 1 11 20 7
    truck 16 3 6 7
    turtle 16 5 8 9
    umbrella 17 19 2 9
    yoyo 15 17 19 7
    zebra 10 14 16 17
    elephant 1 12 16 18
    goldfish 3 7 8 10
    hat 1 2 5 18
    kite 4 6 10 15
    motorcycle 1 3 9 18
    mouse 1 8 9 17
    flag 3 9 5 2
    frog 3 4 20 9
    gametarget 1 2 7 13
    hand 2 3 9 16
    helmet 5 11 19 13
    licenseplate 6 12 13 15
    electricfan 1 10 18 20
    chameleon 3 6 11 20
    crocodile 3 4 10 14
    gecko 1 5 16 19
    fox 2 3 5 20
    giraffe 2 10 13 15
    gorilla 4 6 9 13
    hippo 1 7 9 20
    horse 1 4 12 15
    kangaroo 2 5 11 14
    leopard 1 7 16 20
    lion 1 5 12 20
    lizard 1 3 6 13
    microphone 2 6 14 16
    monkey 3 4 9 17
    shark 2 3 5 6
    squirrel 8 11 13 19
    volleyball 1 13 18 19
"""

LASOT_TEST = [f"{line.split()[0]}-{number}" for line in _LASOT_TEST.strip().splitlines()
              for number in line.split()[1:]]

#: Subset name -> the folder (or sequence) names it holds.
SUBSETS: dict[str, list[str]] = {
    "otb2013": OTB2013_FOLDERS,
    "otb50": OTB50_FOLDERS,
    "otb100": OTB100_FOLDERS,
    "lasot-test": LASOT_TEST,
}
